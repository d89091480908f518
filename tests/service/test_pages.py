"""The dashboard's pages as HTML, without a browser: what reads without JavaScript, the 404
page, the filters that ignore junk, and browser code served from installed packages."""

from __future__ import annotations

import re
import threading

from nanonav.scenario import Scenario
from nanonav.settings import Settings
from nanonav.store import JobStatus, StudyJob, StudyStore
from tests.conftest import Api
from worker.job import run_job

TINY = {"robots": {"count": 2}, "learning": {"episodes": 1, "max_steps": 40},
        "evaluation": {"worlds": 2}}  # fmt: skip


def succeeded(api: Api, settings: Settings) -> int:
    scenario = Scenario.model_validate(TINY).model_dump(mode="json")
    job = api.store.enqueue(scenario, robot_steps=1, episodes=3)
    claim = api.store.claim("test", lease_s=30)
    assert claim is not None
    record = run_job(api.store, claim, settings, threading.Event())
    assert record is not None and record.status is JobStatus.SUCCEEDED
    return job.id


def test_a_finished_jobs_page_reads_without_javascript(api: Api, api_settings: Settings) -> None:
    job_id = succeeded(api, api_settings)
    page = api.client.get(f"/ui/jobs/{job_id}")
    assert page.status_code == 200 and page.headers["content-type"].startswith("text/html")
    html = page.text
    assert f"Job #{job_id}" in html and "succeeded" in html
    for label in ("Total Steps", "Final Distance", "Average Distance", "Success Rate"):
        assert f'<th scope="row">{label}</th>' in html, label
    assert "mean over 2 evaluation worlds" in html
    for picture in ("plots/learning.png", "heatmap.png?plane=xy", "plots/qtable.png"):
        assert f"/jobs/{job_id}/{picture}" in html
    assert 'id="progress-card"' not in html  # nothing left to follow


def test_pages_load_nothing_from_other_hosts(api: Api, api_settings: Settings) -> None:
    job_id = succeeded(api, api_settings)
    for path in ("/", "/ui/jobs", f"/ui/jobs/{job_id}", "/ui/studies", "/ui/studies/new",
                 "/docs"):  # fmt: skip
        html = api.client.get(path).text
        sources = re.findall(r'(?:src|href)="([^"]+)"', html)
        assert sources, path
        assert all(not s.startswith(("http:", "https:", "//")) for s in sources), (path, sources)


def test_browser_code_comes_from_installed_packages(api: Api) -> None:
    plotly = api.client.get("/static/vendor/plotly.min.js")
    assert plotly.status_code == 200 and len(plotly.content) > 1_000_000
    assert b"plotly" in plotly.content[:2000].lower()
    swagger = api.client.get("/static/vendor/swagger-ui-bundle.js")
    assert swagger.status_code == 200 and b"SwaggerUIBundle" in swagger.content
    assert api.client.get("/static/vendor/nothing.js").status_code == 404
    assert api.client.get("/static/app.css").status_code == 200
    docs = api.client.get("/docs").text
    assert "/static/vendor/swagger-ui-bundle.js" in docs and "cdn" not in docs


def test_unknown_jobs_and_studies_get_a_404_page(api: Api) -> None:
    for path in ("/ui/jobs/77", "/ui/studies/77", "/ui/studies/77/results"):
        page = api.client.get(path)
        assert page.status_code == 404 and "There is no" in page.text


def test_the_jobs_page_filters_and_ignores_junk(api: Api) -> None:
    for policy in ("gradient", "rule", "gradient"):
        api.client.post("/jobs", json={"robots": {"policy": policy}})
    html = api.client.get("/ui/jobs", params={"policy": "gradient"}).text
    assert html.count(">gradient</td>") == 2 and ">rule</td>" not in html
    junk = api.client.get("/ui/jobs", params={"policy": "nope", "status": "x", "study": "-1"})
    assert junk.status_code == 200 and junk.text.count("<tr>") == 1 + 3


def test_a_studys_page_shows_its_table(api: Api) -> None:
    spec = {"name": "s", "base": {}, "grid": {"robots.count": [1, 2]}, "seeds": [0],
            "compare": None}  # fmt: skip
    record = StudyStore(api.store.engine).create(
        name="s", spec=spec,
        jobs=[StudyJob({"robots": {"count": n}}, 1, 1, i, 0) for i, n in enumerate((1, 2))],
    )  # fmt: skip
    html = api.client.get(f"/ui/studies/{record.id}").text
    assert 'id="points-table"' in html and html.count("0/1") == 2
    fragment = api.client.get(f"/ui/studies/{record.id}/results").text
    assert 'data-status="queued"' in fragment
