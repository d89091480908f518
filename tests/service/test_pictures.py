"""Pictures are drawn the first time they are asked for, once, off the event loop, then kept."""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Iterator
from concurrent.futures import ThreadPoolExecutor
from typing import Any

import httpx
import pytest

from nanonav import plots
from nanonav.engine import SimulationResult
from nanonav.settings import Settings
from nanonav.store import JobStatus, JobStore
from nanonav.store.migrate import upgrade
from service.app import create_app
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
    real = plots.render

    def counted(result: SimulationResult, name: str, **options: Any) -> bytes:
        asked = "&".join(f"{key}={value}" for key, value in sorted(options.items()))
        names.append(f"{name}?{asked}" if asked else name)
        time.sleep(0.2)
        return real(result, name, **options)

    monkeypatch.setattr(plots, "render", counted)
    yield names


def test_a_picture_is_drawn_on_first_request_and_then_read(
    api: Api, api_settings: Settings, drawn: list[str]
) -> None:
    job_id = succeeded_job(api.store, api_settings)
    assert api.store.plot(job_id, "trajectory") is None
    first = api.client.get(f"/jobs/{job_id}/plots/trajectory.png")
    assert first.status_code == 200, first.text
    assert first.headers["content-type"] == "image/png"
    assert "immutable" in first.headers["cache-control"]
    assert api.store.plot(job_id, "trajectory") == first.content
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
        params={"plane": "yz", "resolution": plots.HEATMAP_RESOLUTION},
    )
    assert default.status_code == named.status_code == 200
    assert named.content == default.content == api.store.plot(job_id, "heatmap_yz")
    assert drawn == ["heatmap_yz"]


def test_a_heatmap_at_a_chosen_slice_and_resolution_is_drawn_for_each_request(
    api: Api, api_settings: Settings, drawn: list[str]
) -> None:
    job_id = succeeded_job(api.store, api_settings)
    url = f"/jobs/{job_id}/heatmap.png"
    chosen = {"plane": "xy", "at": 3.5, "resolution": 40}
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
    real: Callable[[SimulationResult, str], bytes] = plots.render

    def blocked(result: SimulationResult, name: str) -> bytes:
        started.set()
        release.wait(10)
        return real(result, name)

    monkeypatch.setattr(plots, "render", blocked)
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
