"""The dashboard's pages as HTML, without a browser: what reads without JavaScript, the 404
page, the filters that ignore junk, and browser code served from installed packages."""

from __future__ import annotations

import html as markup
import json
import re
import threading
from datetime import UTC, datetime
from typing import Any

import httpx
import numpy as np
import pytest

from nanonav.engine import qlearning, simulate
from nanonav.pictures import job as job_pictures
from nanonav.scenario import Scenario
from nanonav.settings import Settings
from nanonav.store import JobStatus, StudyJob, StudyStore
from tests.conftest import SCRIPTED, Api
from tests.service.test_security import KEY_A, KEY_B, bearer, served
from worker.job import outcome, run_job

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
    for label in ("Total Steps", "Final Distance (length units)",
                  "Average Distance (length units)", "Success Rate"):  # fmt: skip
        assert f'<th scope="row">{label}</th>' in html, label
    assert "mean over 2 evaluation worlds" in html
    heatmap = f"heatmap.png?plane=xy&amp;v={job_pictures.version('heatmap_xy')}"
    for picture in ("plots/learning.png", heatmap, "plots/qtable.png"):
        assert f"/jobs/{job_id}/{picture}" in html
    assert 'id="progress-card"' not in html  # nothing left to follow


def test_pages_load_nothing_from_other_hosts(api: Api, api_settings: Settings) -> None:
    job_id = succeeded(api, api_settings)
    for path in ("/", "/ui/jobs", f"/ui/jobs/{job_id}", "/ui/studies", "/ui/studies/new",
                 "/ui/policies", "/docs"):  # fmt: skip
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


def a_study_of_two_jobs(api: Api) -> list[int]:
    """The ids of the two queued jobs of a new study."""
    spec = {"name": "s", "base": {}, "grid": {"robots.count": [1, 2]}, "seeds": [0],
            "compare": None}  # fmt: skip
    record = StudyStore(api.store.engine).create(
        name="s", spec=spec,
        jobs=[StudyJob({"robots": {"count": n}}, 1, 1, i, 0) for i, n in enumerate((1, 2))],
    )  # fmt: skip
    page = api.store.page(status=None, limit=10, before_id=None, study_id=record.id)
    return [job.id for job in page.jobs]


def test_the_home_page_lists_only_the_jobs_of_no_study(api: Api) -> None:
    alone = api.client.post("/jobs", json={"robots": {"policy": "rule"}}).json()["id"]
    in_study = a_study_of_two_jobs(api)
    html = api.client.get("/").text
    listed = {int(i) for i in re.findall(r'href="/ui/jobs/(\d+)"', html)}
    assert listed == {alone}, (listed, in_study)
    assert len(api.store.page(status=None, limit=10, before_id=None, standalone=True).jobs) == 1


def test_job_lists_show_each_succeeded_jobs_success_rate(api: Api, api_settings: Settings) -> None:
    done = succeeded(api, api_settings)
    waiting = api.client.post("/jobs", json=TINY).json()["id"]
    expected = api.store.metrics(done)["summary"]["success_rate"]
    assert api.store.headlines([done, waiting, 10**6]).keys() == {done}
    for path in ("/", "/ui/jobs"):
        html = api.client.get(path).text
        assert 'title="greedy success rate over the evaluation worlds">Success</th>' in html
        row = r'<tr>\s*<td><a href="/ui/jobs/(\d+)">(.*?)</tr>'
        rows = {int(job): cells for job, cells in re.findall(row, html, re.S)}
        shown = re.findall(r'<td class="num">([^<]*)</td>', rows[done])
        assert shown == [f"{expected:.2f}"], (path, rows[done])
        assert re.findall(r'<td class="num">([^<]*)</td>', rows[waiting]) == [""], path


def form_json(html: str) -> object:
    found = re.search(r'<textarea id="scenario-json"[^>]*>(.*?)</textarea>', html, re.S)
    assert found is not None
    return json.loads(markup.unescape(found.group(1)))


def test_a_job_is_run_again_from_the_form_filled_in_with_its_scenario_and_seed(
    api: Api,
) -> None:
    job_id = api.client.post("/jobs", json={"preset": "paper-swarm", "seed": 7}).json()["id"]
    page = api.client.get(f"/ui/jobs/{job_id}").text
    assert f'href="/?from={job_id}"' in page and "seed 7" in page and "repeats" in page
    home = api.client.get("/", params={"from": job_id}).text
    assert form_json(home) == api.store.get(job_id).scenario
    assert f"job #{job_id}</a>, with its seed 7" in home and "repeats that job exactly" in home
    for junk in ("abc", "-1", "0", "999", "9" * 20):
        answer = api.client.get("/", params={"from": junk})
        assert answer.status_code == 200 and form_json(answer.text) == {}, junk
        assert 'id="from-job"' not in answer.text


def test_every_picture_says_it_is_drawing_and_links_to_itself(
    api: Api, api_settings: Settings
) -> None:
    job_id = succeeded(api, api_settings)
    study_job = a_study_of_two_jobs(api)[0]
    study_id = api.client.get(f"/jobs/{study_job}").json()["study_id"]
    for path in (f"/ui/jobs/{job_id}", f"/ui/studies/{study_id}"):
        html = api.client.get(path).text
        images = re.findall(r'<img src="([^"]+)"', html)
        wrapped = re.findall(
            r'<a class="picture" href="([^"]+)"[^>]*><span class="drawing">drawing…</span>'
            r'<img src="([^"]+)"',
            html,
        )
        assert len(images) >= 4 and len(wrapped) == len(images), path
        assert all(href == src for href, src in wrapped), wrapped


def test_an_active_brownian_jobs_page_says_its_physics_and_units(
    api: Api, api_settings: Settings
) -> None:
    scenario = Scenario.model_validate(
        {
            "physics": {"model": "active_brownian"},
            "robots": {"count": 2, "policy": "gradient"},
            "learning": {"episodes": 0, "max_steps": 30},
            "evaluation": {"worlds": 1},
        }
    ).model_dump(mode="json")
    job = api.store.enqueue(scenario, robot_steps=1, episodes=1)
    claim = api.store.claim("test", lease_s=30)
    assert claim is not None
    record = run_job(api.store, claim, api_settings, threading.Event())
    assert record is not None and record.status is JobStatus.SUCCEEDED
    html = api.client.get(f"/ui/jobs/{job.id}").text
    assert "active Brownian robots of 1.0 µm swimming at 10.0 µm/s" in html
    assert " um" not in html, "lengths are in µm"
    assert "steps of 0.01 s (0.3 s in all)" in html and "gaussian field" not in html
    for name in ("trajectory", "concentration", "learning"):
        picture = api.client.get(f"/jobs/{job.id}/plots/{name}.png")
        assert picture.status_code == 200 and picture.content.startswith(b"\x89PNG"), name


def send_policy(client: httpx.Client, actions: str, communication: str, robots: int = 0,
                headers: dict[str, str] | None = None) -> dict[str, Any]:  # fmt: skip
    states, labels = qlearning.labels(actions, communication)
    shape = (robots, len(states), len(labels)) if robots else (len(states), len(labels))
    body = {"name": f"{actions} table", "states": states, "actions": labels,
            "values": np.zeros(shape).tolist()}  # fmt: skip
    response = client.post("/policies", json=body, headers=headers)
    assert response.status_code == 201, response.text
    answer: dict[str, Any] = response.json()
    return answer


def test_the_policies_page_lists_them_and_the_form_evaluates_one(api: Api) -> None:
    assert "No policies yet" in api.client.get("/ui/policies").text
    per_robot = send_policy(api.client, "directions", "none", robots=3)
    steering = send_policy(api.client, "steering", "broadcast")
    html = api.client.get("/ui/policies").text
    rows = re.findall(r'<a href="/ui/policies/(\d+)">#\d+</a>', html)
    assert rows == [str(steering["id"]), str(per_robot["id"])]
    assert f'href="/?policy={per_robot["id"]}"' in html
    assert "one per robot of 3" in html and "broadcast" in html
    expected = {
        per_robot["id"]: {"policy_from": per_robot["policy_from"], "robots": {"count": 3},
                          "learning": {"episodes": 0, "actions": "directions",
                                       "shared_table": False}},
        steering["id"]: {"policy_from": steering["policy_from"],
                         "physics": {"model": "active_brownian"},
                         "communication": {"model": "broadcast"},
                         "learning": {"episodes": 0, "actions": "steering"}},
    }  # fmt: skip
    for policy_id, scenario in expected.items():
        form = api.client.get("/", params={"policy": policy_id}).text
        assert 'id="from-policy"' in form and f"policy-{policy_id}" in form
        assert form_json(form) == scenario
        job = api.client.post("/jobs", json=scenario)
        assert job.status_code == 202, job.text  # the form as filled in is an evaluation
    for junk in ("999", "x", "-1", "0"):
        form = api.client.get("/", params={"policy": junk}).text
        assert 'id="from-policy"' not in form and form_json(form) == {}, junk


def test_another_keys_policies_are_neither_listed_nor_filled_in(sqlite_url: str) -> None:
    settings = Settings(database_url=sqlite_url, api_keys=f"{KEY_A},{KEY_B}")
    with served(settings) as api:
        mine = send_policy(api.client, "behaviors", "none", headers=bearer(KEY_A))
        theirs = api.client.get("/ui/policies", headers=bearer(KEY_B)).text
        assert "No policies yet" in theirs
        assert (
            f"/ui/policies/{mine['id']}"
            in api.client.get("/ui/policies", headers=bearer(KEY_A)).text
        )
        form = api.client.get("/", params={"policy": mine["id"]}, headers=bearer(KEY_B)).text
        assert form_json(form) == {}


def test_ids_in_a_pages_query_are_ascii_digits_or_ignored(api: Api) -> None:
    job = api.client.post("/jobs", json=TINY).json()["id"]
    api.client.post("/jobs", json=TINY)
    policy = send_policy(api.client, "directions", "none")["id"]
    assert job == policy == 1
    # superscript 2 and circled 1 pass str.isdigit and make int() fail; int() reads the
    # Arabic-Indic and the fullwidth 1 as 1
    for junk in ("%C2%B2", "%E2%91%A0", "%D9%A1", "%EF%BC%91", "01", "+1"):
        for name in ("from", "policy"):
            answer = api.client.get(f"/?{name}={junk}")
            assert answer.status_code == 200 and form_json(answer.text) == {}, (name, junk)
        listed = api.client.get(f"/ui/jobs?study={junk}")
        assert listed.status_code == 200 and listed.text.count("<tr>") == 1 + 2, junk


# ---------------------------------------------------------------- policies, forms, login


def test_a_policys_page_shows_its_greedy_table_and_is_linked_wherever_it_is_named(
    api: Api,
) -> None:
    from tests.service.test_network_policies import OBSERVATION, network

    sent = send_policy(api.client, "directions", "none")
    states, _ = qlearning.labels("directions", "none")
    page = api.client.get(f"/ui/policies/{sent['id']}")
    assert page.status_code == 200 and page.headers["content-type"].startswith("text/html")
    html = page.text
    assert f"Policy #{sent['id']}" in html and "directions table" in html
    assert f'policy_from: "{sent["policy_from"]}"' in markup.unescape(html)
    assert html.count("<tr><td><code>") == len(states)
    assert f'href="/?policy={sent["id"]}"' in html and f'href="/policies/{sent["id"]}"' in html
    # linked from the list, the form that evaluates it and the job that did
    assert f'href="/ui/policies/{sent["id"]}"' in api.client.get("/ui/policies").text
    form = api.client.get("/", params={"policy": sent["id"]}).text
    assert f'<a href="/ui/policies/{sent["id"]}">policy #{sent["id"]}</a>' in form
    job = api.client.post("/jobs", json=form_json(form)).json()["id"]
    assert f'href="/ui/policies/{sent["id"]}"' in api.client.get(f"/ui/jobs/{job}").text
    model = network(api, name="mlp")
    html = api.client.get(f"/ui/policies/{model['id']}").text
    assert "A network (an ONNX model)" in html
    assert all(f"<code><bdi>{label}</bdi></code>" in html for label in OBSERVATION)
    assert f'href="/policies/{model["id"]}/model"' in html
    assert api.client.get(f"/ui/policies/{model['id'] + 1}").status_code == 404


def test_the_seed_field_says_a_blank_seed_is_drawn_at_random(api: Api) -> None:
    seed = re.search(r'<input name="seed"[^>]*>', api.client.get("/").text)
    assert seed is not None and 'placeholder="random"' in seed.group(0)


def test_a_form_asked_to_start_from_what_is_not_there_says_so(api: Api) -> None:
    for query, note in (
        ("from=77", "There is no job 77 to fill the form in from: it holds the defaults."),
        ("from=new", "There is no job &#39;new&#39; to fill the form in from"),
        ("policy=5", "There is no policy 5 to fill the form in from"),
    ):
        page = api.client.get(f"/ui/jobs/new?{query}", follow_redirects=True)
        assert page.status_code == 200 and str(page.url).endswith(f"/?{query}")
        assert note in page.text and form_json(page.text) == {}, query
    assert "unknown-source" not in api.client.get("/").text


@pytest.mark.parametrize(("ttl_s", "lasts"), [(None, "8 hours"), (5400, "90 minutes"),
                                              (86400, "1 day")])  # fmt: skip
def test_the_login_page_says_how_long_a_session_lasts(
    sqlite_url: str, ttl_s: float | None, lasts: str
) -> None:
    settings = Settings(database_url=sqlite_url, api_keys=f"{KEY_A},{KEY_B}")
    if ttl_s is not None:
        settings = settings.model_copy(update={"session_ttl_s": ttl_s})
    with served(settings) as api:
        html = api.client.get("/ui/login").text
    assert f"gives this browser a session for {lasts}" in html
    assert "Closing the\nbrowser does not end it" in html and "until it closes" not in html


def test_with_keys_an_empty_list_says_what_was_made_before_keys_is_not_shown(
    sqlite_url: str,
) -> None:
    with served(Settings(database_url=sqlite_url)) as api:
        before = api.client.post("/jobs", json=TINY, headers=SCRIPTED)
        assert before.status_code == 202, before.text
        job = before.json()["id"]
        assert api.store.get(job).owner == ""
        assert "ownerless-note" not in api.client.get("/ui/jobs").text
    settings = Settings(database_url=sqlite_url, api_keys=f"{KEY_A},{KEY_B}")
    with served(settings) as api:
        listed = api.client.get("/ui/jobs", headers=bearer(KEY_A)).text
        assert "No jobs yet." in listed and 'id="ownerless-note"' in listed
        assert f"/ui/jobs/{job}" not in listed
        assert api.client.get(f"/jobs/{job}", headers=bearer(KEY_A)).status_code == 404
        assert api.client.get(f"/ui/jobs/{job}", headers=bearer(KEY_B)).status_code == 404
        assert api.store.get(job).owner == ""  # kept as it was
        for page, what in (("/ui/studies", "studies"), ("/ui/policies", "policies")):
            empty = api.client.get(page, headers=bearer(KEY_A)).text
            assert 'id="ownerless-note"' in empty and f"Only the {what} of the key" in empty
        mine = api.client.post("/jobs", json=TINY, headers=bearer(KEY_A))
        assert mine.status_code == 202
        assert "ownerless-note" not in api.client.get("/ui/jobs", headers=bearer(KEY_A)).text
    with served(Settings(database_url=sqlite_url)) as api:
        assert f"/ui/jobs/{job}" in api.client.get("/ui/jobs").text


def test_the_banner_says_what_the_workers_do_in_words_that_count(api: Api) -> None:
    """A worker preparing the engine is named as such, not "no worker is running: start one";
    one job is "1 job"."""
    api.store.enqueue(Scenario.model_validate(TINY).model_dump(mode="json"), robot_steps=1,
                      episodes=3)  # fmt: skip

    def banner() -> str:
        page = api.client.get("/ui/jobs").text
        found = re.search(r'<p class="note warn">(.*?)</p>', page, re.S)
        assert found is not None, "no note"
        return markup.unescape(found.group(1))

    assert banner() == ("1 job is queued but no worker has been seen in the last 30 s: start "
                        "one with `nanonav worker`.")  # fmt: skip
    api.store.worker_seen("box:1", started_at=datetime.now(UTC), ready=False)
    assert banner() == ("1 worker is preparing the engine (a first start compiles it: about a "
                        "minute); queued jobs wait for it.")  # fmt: skip
    assert "1 preparing" in api.client.get("/ui/jobs").text
    api.store.worker_seen("box:1", started_at=datetime.now(UTC))
    assert '<p class="note warn">' not in api.client.get("/ui/jobs").text


def test_the_jobs_list_names_the_policy_a_job_evaluates(api: Api) -> None:
    """It said "q_learning (behaviors)" for a job that evaluates a policy sent from elsewhere."""
    sent = send_policy(api.client, "behaviors", "none")
    scenario = {"policy_from": sent["policy_from"], "learning": {"episodes": 0}}
    assert api.client.post("/jobs", json=scenario).status_code == 202
    page = api.client.get("/ui/jobs").text
    assert f'<a href="/ui/policies/{sent["id"]}">{sent["policy_from"]}</a>, sent' in page
    assert "q_learning (behaviors)" not in page


def test_a_cancelled_jobs_page_shows_the_learning_curve_it_had(api: Api) -> None:
    """A job cancelled while it trained keeps the episodes it finished: its page draws their
    learning curve, and says there is no evaluation, rather than showing nothing."""
    scenario = Scenario.model_validate({"learning": {"episodes": 20_000, "max_steps": 200}})
    job = api.store.enqueue(scenario.model_dump(mode="json"), robot_steps=1, episodes=20_020)
    claim = api.store.claim("test", lease_s=30)
    assert claim is not None
    api.store.finish(claim, outcome(simulate(scenario, lambda progress: False)))
    page = api.client.get(f"/ui/jobs/{job.id}")
    assert page.status_code == 200
    learning = api.client.get(f"/jobs/{job.id}").json()["links"]["plots"]["learning"]
    assert f'<img src="{learning}"' in page.text
    assert "Learning curve, until the cancel" in page.text
    assert "there is no evaluation to show, only the training episodes it finished" in page.text
    assert "/plots/trajectory.png" not in page.text
    assert api.client.get(learning).content.startswith(b"\x89PNG")
