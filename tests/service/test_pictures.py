"""Pictures are drawn the first time they are asked for, once, off the event loop, then kept."""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Iterator
from concurrent.futures import ThreadPoolExecutor

import httpx
import pytest

from nanonav import plots
from nanonav.engine import SimulationResult
from nanonav.settings import Settings
from nanonav.store import JobStatus, JobStore
from nanonav.store.migrate import upgrade
from service.app import create_app
from tests.conftest import Api, serve
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
    """The names of the pictures the API draws, in order; each drawing takes a little while,
    so that requests made together overlap."""
    names: list[str] = []
    real = plots.render

    def counted(result: SimulationResult, name: str) -> bytes:
        names.append(name)
        time.sleep(0.2)
        return real(result, name)

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
