"""Pictures are drawn the first time they are asked for, once, off the event loop, then kept."""

from __future__ import annotations

import json
import threading
import time
from collections.abc import Callable, Iterator
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

import httpx
import pytest

from nanonav import cli
from nanonav.engine import SimulationResult
from nanonav.pictures import job as pictures
from nanonav.settings import Settings
from nanonav.store import JobStatus, JobStore, StudyStore
from nanonav.store.migrate import upgrade
from service.app import create_app
from service.drawing import kept_name
from tests.conftest import Api, serve
from tests.service.test_api import assert_problem
from worker.job import run_job

TINY = {"robots": {"count": 2}, "learning": {"episodes": 1, "max_steps": 60}}


def succeeded_job(store: JobStore, settings: Settings) -> int:
    """A job run to success in this process, as a worker would."""
    job = store.enqueue(TINY, robot_steps=1, episodes=2)
    claim = store.claim("test", lease_s=30)
    assert claim is not None
    record = run_job(store, claim, settings, threading.Event())
    assert record is not None and record.status is JobStatus.SUCCEEDED
    return job.id


@pytest.fixture
def drawn(monkeypatch: pytest.MonkeyPatch) -> Iterator[list[str]]:
    """The names of the pictures the API draws, in order (with the slice and resolution asked
    for, if any); each drawing takes a little while, so that requests made together overlap."""
    names: list[str] = []
    real = pictures.render

    def counted(result: SimulationResult, name: str, **options: Any) -> bytes:
        asked = "&".join(f"{key}={value}" for key, value in sorted(options.items()))
        names.append(f"{name}?{asked}" if asked else name)
        time.sleep(0.2)
        return real(result, name, **options)

    monkeypatch.setattr(pictures, "render", counted)
    yield names


def test_a_picture_is_drawn_on_first_request_and_then_read(
    api: Api, api_settings: Settings, drawn: list[str]
) -> None:
    job_id = succeeded_job(api.store, api_settings)
    kept_as = kept_name("trajectory", pictures.version("trajectory"))
    assert api.store.plot(job_id, kept_as) is None
    first = api.client.get(f"/jobs/{job_id}/plots/trajectory.png")
    assert first.status_code == 200, first.text
    assert first.headers["content-type"] == "image/png"
    assert "immutable" in first.headers["cache-control"]
    assert api.store.plot(job_id, kept_as) == first.content
    again = api.client.get(f"/jobs/{job_id}/plots/trajectory.png")
    assert again.content == first.content
    assert drawn == ["trajectory"]


def test_requests_for_the_same_picture_at_once_share_one_drawing(
    api: Api, api_settings: Settings, drawn: list[str]
) -> None:
    job_id = succeeded_job(api.store, api_settings)

    def fetch(_: int) -> bytes:
        with httpx.Client(base_url=api.url, timeout=30) as client:
            response = client.get(f"/jobs/{job_id}/heatmap.png", params={"plane": "xz"})
            assert response.status_code == 200, response.text
            return response.content

    with ThreadPoolExecutor(6) as pool:
        bodies = list(pool.map(fetch, range(6)))
    assert drawn == ["heatmap_xz"]
    assert len(set(bodies)) == 1


def test_the_default_heatmap_is_stored_whether_or_not_its_resolution_is_named(
    api: Api, api_settings: Settings, drawn: list[str]
) -> None:
    job_id = succeeded_job(api.store, api_settings)
    default = api.client.get(f"/jobs/{job_id}/heatmap.png", params={"plane": "yz"})
    named = api.client.get(
        f"/jobs/{job_id}/heatmap.png",
        params={"plane": "yz", "resolution": pictures.HEATMAP_RESOLUTION},
    )
    assert default.status_code == named.status_code == 200
    kept = kept_name("heatmap_yz", pictures.version("heatmap_yz"))
    assert named.content == default.content == api.store.plot(job_id, kept)
    assert drawn == ["heatmap_yz"]


def test_a_heatmap_at_a_chosen_slice_and_resolution_is_drawn_for_each_request(
    api: Api, api_settings: Settings, drawn: list[str]
) -> None:
    job_id = succeeded_job(api.store, api_settings)
    url = f"/jobs/{job_id}/heatmap.png"
    chosen: dict[str, str | float] = {"plane": "xy", "at": 3.5, "resolution": 40}
    first = api.client.get(url, params=chosen)
    assert first.status_code == 200, first.text
    assert first.headers["content-type"] == "image/png"
    assert first.headers["cache-control"] == "max-age=86400, immutable"
    assert first.content.startswith(b"\x89PNG")
    assert api.store.plot(job_id, "heatmap_xy") is None  # not stored
    again = api.client.get(url, params=chosen)
    assert again.content == first.content
    assert drawn == ["heatmap_xy?at=3.5&resolution=40"] * 2
    coarse = api.client.get(url, params={"plane": "xy", "resolution": 20})
    default = api.client.get(url, params={"plane": "xy"})
    assert len({first.content, coarse.content, default.content}) == 3
    assert drawn[2:] == ["heatmap_xy?at=None&resolution=20", "heatmap_xy"]


def test_requests_for_the_same_chosen_slice_at_once_share_one_drawing(
    api: Api, api_settings: Settings, drawn: list[str]
) -> None:
    job_id = succeeded_job(api.store, api_settings)

    def fetch(at: float) -> bytes:
        with httpx.Client(base_url=api.url, timeout=30) as client:
            response = client.get(
                f"/jobs/{job_id}/heatmap.png", params={"plane": "xz", "at": at, "resolution": 30}
            )
            assert response.status_code == 200, response.text
            return response.content

    with ThreadPoolExecutor(6) as pool:
        bodies = list(pool.map(fetch, [-2.0, -2.0, -2.0, 4.0, 4.0, 4.0]))
    assert sorted(drawn) == [
        "heatmap_xz?at=-2.0&resolution=30",
        "heatmap_xz?at=4.0&resolution=30",
    ]
    assert len(set(bodies[:3])) == len(set(bodies[3:])) == 1
    assert bodies[0] != bodies[3]


def test_a_slice_outside_the_jobs_cube_is_422_naming_at(
    api: Api, api_settings: Settings, drawn: list[str]
) -> None:
    job = api.store.enqueue({"space": {"size": 10.0}}, robot_steps=1, episodes=1)
    for at in (5.5, -5.01):
        body = assert_problem(api.client.get(f"/jobs/{job.id}/heatmap.png", params={"at": at}), 422)
        assert body["errors"][0]["parameter"] == "at"
        assert "[-5, 5]" in body["errors"][0]["detail"]
    # Within the cube, a job that has not run yet has nothing to draw.
    assert_problem(api.client.get(f"/jobs/{job.id}/heatmap.png", params={"at": 5.0}), 409)
    assert_problem(api.client.get("/jobs/99/heatmap.png", params={"at": 1.0}), 404)
    assert drawn == []


def test_pictures_beyond_the_drawing_queue_are_refused_with_503(
    sqlite_url: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    settings = Settings(database_url=sqlite_url, drawing_queue=1)
    upgrade(sqlite_url)
    store = JobStore.from_url(sqlite_url)
    job_id = succeeded_job(store, settings)
    release = threading.Event()
    started = threading.Event()
    real: Callable[[SimulationResult, str], bytes] = pictures.render

    def blocked(result: SimulationResult, name: str) -> bytes:
        started.set()
        release.wait(10)
        return real(result, name)

    monkeypatch.setattr(pictures, "render", blocked)
    with serve(create_app(settings)) as url, httpx.Client(base_url=url, timeout=30) as client:
        with ThreadPoolExecutor(1) as pool:
            slow = pool.submit(client.get, f"/jobs/{job_id}/plots/trajectory.png")
            assert started.wait(10)
            busy = client.get(f"/jobs/{job_id}/plots/learning.png")
            assert busy.status_code == 503
            assert busy.headers["retry-after"] == "2"
            assert busy.json()["type"].endswith("drawing-busy")
            answer = client.get(f"/jobs/{job_id}")
            assert answer.status_code == 200  # the event loop answers while a picture is drawn
            release.set()
            assert slow.result().status_code == 200
        assert client.get(f"/jobs/{job_id}/plots/learning.png").status_code == 200
    store.close()


def test_the_served_learning_curve_and_qtable_are_the_ones_nanonav_run_writes(
    api: Api, api_settings: Settings, tmp_path: Path
) -> None:
    job_id = succeeded_job(api.store, api_settings)
    scenario = tmp_path / "scenario.json"
    scenario.write_text(json.dumps(api.store.metrics(job_id)["scenario"]), encoding="utf-8")
    out = tmp_path / "run"
    assert cli.main(["run", "--scenario", str(scenario), "--out", str(out)]) == 0
    links = api.client.get(f"/jobs/{job_id}").json()["links"]["plots"]
    for name in ("learning", "qtable"):
        served = api.client.get(links[name])
        assert served.status_code == 200, served.text
        assert served.content == (out / f"{name}.png").read_bytes(), name


def test_a_learning_curve_kept_from_an_older_drawing_is_drawn_again(
    api: Api, api_settings: Settings, drawn: list[str]
) -> None:
    job_id = succeeded_job(api.store, api_settings)
    api.store.save_plot(job_id, "learning", b"kept before the curve showed its evaluation")
    link = api.client.get(f"/jobs/{job_id}").json()["links"]["plots"]["learning"]
    assert link == f"/jobs/{job_id}/plots/learning.png?v=3"
    bodies = set()
    for url in (link, link, f"/jobs/{job_id}/plots/learning.png"):
        served = api.client.get(url)
        assert served.status_code == 200, served.text
        assert served.content.startswith(b"\x89PNG")
        bodies.add(served.content)
    assert len(bodies) == 1
    assert drawn == ["learning"]  # drawn once more, then kept beside the old copy


def test_the_jobs_page_shows_the_pictures_its_links_name(api: Api, api_settings: Settings) -> None:
    job_id = succeeded_job(api.store, api_settings)
    links = api.client.get(f"/jobs/{job_id}").json()["links"]["plots"]
    assert set(links) == {"trajectory", "concentration", "learning", "qtable"}
    page = api.client.get(f"/ui/jobs/{job_id}").text
    for url in links.values():
        assert f'<img src="{url}"' in page, url


def test_a_study_picture_kept_from_an_older_drawing_is_drawn_again(api: Api) -> None:
    study = {"base": TINY, "grid": {"robots.policy": ["q_learning", "gradient"]}, "seeds": [0]}
    created = api.client.post("/studies", json=study)
    assert created.status_code == 202, created.text
    study_id = created.json()["id"]
    assert api.client.post(f"/studies/{study_id}/cancel").json()["status"] == "cancelled"
    stale = b"kept before the series were named in words"
    StudyStore(api.store.engine).keep_plot(study_id, "learning", stale)
    served = [api.client.get(f"/studies/{study_id}/plots/learning.png") for _ in range(2)]
    assert all(s.status_code == 200 and s.content.startswith(b"\x89PNG") for s in served)
    assert served[0].content == served[1].content != stale
    assert "immutable" in served[0].headers["cache-control"]  # the study is over: kept
