"""Event streams end to end: a real ``python -m worker`` runs the jobs, clients watch them."""

from __future__ import annotations

import asyncio
import contextlib
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import httpx
import pytest
from sqlalchemy import event

from nanonav.settings import Settings
from service.app import create_app
from tests.conftest import SCRIPTED, Api, serve
from tests.e2e.test_jobs import LONG, TINY, submit
from tests.processes import FIRST_JOB_S, Worker, clean_environment, free_port
from tests.sse import Message, amessages, events

# About 2.5 s of work (0.5 s with 6 episodes, measured warm, gave a stream, which reads every
# 0.25 s, only two progress events): 30 training episodes and an evaluation world of 50 random
# walkers that use all their steps; the worker writes progress every 0.05 s.
MEDIUM: dict[str, Any] = {
    "space": {"size": 1000},
    "robots": {"count": 50, "policy": "random"},
    "learning": {"episodes": 30, "max_steps": 20_000},
    "evaluation": {"worlds": 1},
}
QUICK_PROGRESS = {"NANONAV_PROGRESS_INTERVAL_S": "0.05"}
STREAMS = 100
WINDOW_S = 2.0

pytestmark = pytest.mark.timeout(240)


def ready_worker(start_worker: Callable[..., Worker]) -> Worker:
    worker = start_worker(**QUICK_PROGRESS)
    worker.wait_ready()
    return worker


def watch(api: Api, path: str) -> list[Message]:
    """Every event of a stream, until the server ends it."""
    with httpx.Client(base_url=api.url, timeout=30) as client, client.stream("GET", path) as r:
        assert r.status_code == 200
        return list(events(r))


def test_a_job_stream_shows_progress_then_succeeded_and_ends(
    api: Api, start_worker: Callable[..., Worker]
) -> None:
    ready_worker(start_worker)
    job_id = submit(api, MEDIUM)
    seen = watch(api, f"/jobs/{job_id}/events")

    statuses = [e.json()["status"] for e in seen if e.event == "status"]
    assert statuses in (["queued", "running", "succeeded"], ["running", "succeeded"])
    progress = [e.json()["progress"]["fraction"] for e in seen if e.event == "progress"]
    assert len(progress) >= 3 and progress[0] > 0
    assert progress == sorted(progress)
    assert all(e.json()["status"] == "running" for e in seen if e.event == "progress")
    assert seen[-1].event == "status"
    assert seen[-1].json() == api.client.get(f"/jobs/{job_id}").json()
    assert seen[-1].json()["progress"]["fraction"] == 1.0
    assert len({e.id for e in seen}) == len(seen)


def test_a_cancelled_job_stream_ends_with_cancelled(
    api: Api, start_worker: Callable[..., Worker]
) -> None:
    ready_worker(start_worker)
    job_id = submit(api, LONG)
    seen: list[Message] = []
    cancelled_at = float("nan")
    with (
        httpx.Client(base_url=api.url, timeout=30) as client,
        client.stream("GET", f"/jobs/{job_id}/events") as response,
    ):
        stream = events(response)
        for found in stream:
            seen.append(found)
            if found.event == "progress" and found.json()["progress"]["fraction"] > 0:
                cancelled_at = time.monotonic()
                api.client.post(f"/jobs/{job_id}/cancel")
                break
        seen.extend(stream)
    assert time.monotonic() - cancelled_at < 5
    assert seen[-1].event == "status"
    assert seen[-1].json()["status"] == "cancelled"
    assert seen[-1].json() == api.client.get(f"/jobs/{job_id}").json()


def test_a_study_stream_ends_when_the_study_is_done(
    api: Api, start_worker: Callable[..., Worker]
) -> None:
    ready_worker(start_worker)
    spec = {"base": TINY, "grid": {"robots.count": [1, 2, 3]}, "seeds": [0, 1]}
    created = api.client.post("/studies", json=spec)
    assert created.status_code == 202
    study_id = created.json()["id"]
    seen = watch(api, f"/studies/{study_id}/events")

    states = [e.json() for e in seen]
    assert states[-1]["status"] == "succeeded" and seen[-1].event == "status"
    whole = api.client.get(f"/studies/{study_id}").json()
    for key in ("id", "status", "jobs", "progress", "finished_at"):
        assert states[-1][key] == whole[key]
    assert states[-1]["jobs"]["succeeded"] == 6 and states[-1]["progress"] == 1.0
    succeeded = [s["jobs"]["succeeded"] for s in states]
    assert succeeded == sorted(succeeded)
    assert set(states[-1]) == {"id", "status", "jobs", "progress", "finished_at"}


def test_a_hundred_streams_cost_one_store_query_per_tick(
    api: Api, start_worker: Callable[..., Worker]
) -> None:
    """The API's own engine counts its SELECTs while 100 clients watch one running job."""
    ready_worker(start_worker)
    # one client address: its streams are let past the default per-key limit
    settings = Settings(
        database_url=api.database_url, events_poll_s=0.25, events_streams_per_key=STREAMS
    )
    app = create_app(settings)
    selects: list[str] = []
    lock = threading.Lock()

    def count(conn: Any, cursor: Any, statement: str, *args: Any) -> None:
        if statement.lstrip().upper().startswith("SELECT"):
            with lock:
                selects.append(statement)

    event.listen(app.state.store.engine, "before_cursor_execute", count)
    with serve(app) as url:
        job_id = httpx.post(f"{url}/jobs", json=LONG).json()["id"]
        path = f"/jobs/{job_id}/events"
        channel, poller = app.state.job_events, app.state.poller

        async def watch_one(client: httpx.AsyncClient) -> list[Message]:
            async with client.stream("GET", path) as response:
                return [m async for m in amessages(response) if m.data is not None]

        async def scenario() -> tuple[list[list[Message]], int, int]:
            limits = httpx.Limits(max_connections=STREAMS + 10)
            async with httpx.AsyncClient(
                base_url=url, timeout=30, limits=limits, headers=SCRIPTED
            ) as client:
                watchers = [asyncio.create_task(watch_one(client)) for _ in range(STREAMS)]
                deadline = time.monotonic() + FIRST_JOB_S
                while channel.listeners < STREAMS or app.state.store.get(job_id).fraction == 0:
                    assert time.monotonic() < deadline, channel.listeners
                    await asyncio.sleep(0.05)
                with lock:
                    selects.clear()
                ticks = poller.ticks
                await asyncio.sleep(WINDOW_S)
                with lock:
                    queries, ticks = len(selects), poller.ticks - ticks
                await client.post(f"/jobs/{job_id}/cancel")
                seen = await asyncio.wait_for(asyncio.gather(*watchers), timeout=30)
                return seen, queries, ticks

        seen, queries, ticks = asyncio.run(scenario())
    assert WINDOW_S / 0.25 - 2 <= ticks <= WINDOW_S / 0.25 + 1
    assert ticks - 1 <= queries <= ticks + 1, (queries, ticks)  # not x 100
    for stream in seen:
        assert stream[-1].event == "status" and stream[-1].json()["status"] == "cancelled"
        assert sum(m.event == "progress" for m in stream) >= WINDOW_S / 0.25 / 2


def test_the_api_stops_within_its_grace_while_a_stream_is_open(api: Api, tmp_path: Path) -> None:
    """An open stream would hold a stopping uvicorn for as long as its client stays; `nanonav
    api` cancels it after NANONAV_SHUTDOWN_GRACE_S."""
    url = f"http://127.0.0.1:{free_port()}"
    env = clean_environment(NANONAV_DATABASE_URL=api.database_url, NANONAV_SHUTDOWN_GRACE_S="1")
    command = [sys.executable, "-m", "nanonav.cli", "api", "--port", url.rsplit(":", 1)[1]]
    with (tmp_path / "api.log").open("wb") as log:
        server = subprocess.Popen(command, env=env, stdout=log, stderr=subprocess.STDOUT)
    try:
        deadline = time.monotonic() + 60
        while True:
            assert server.poll() is None and time.monotonic() < deadline
            try:
                if httpx.get(f"{url}/healthz").status_code == 200:
                    break
            except httpx.TransportError:
                time.sleep(0.05)
        job_id = httpx.post(f"{url}/jobs", json=TINY).json()["id"]  # no worker: stays queued
        opened = threading.Event()
        ended = threading.Event()

        def hold() -> None:
            with (
                contextlib.suppress(httpx.TransportError),
                httpx.stream("GET", f"{url}/jobs/{job_id}/events", timeout=30) as response,
            ):
                for _ in events(response):
                    opened.set()
            ended.set()

        threading.Thread(target=hold, daemon=True).start()
        assert opened.wait(10)
        stopping = time.monotonic()
        server.send_signal(signal.SIGTERM)
        # uvicorn stops gracefully, then re-raises the signal it caught
        assert server.wait(timeout=10) in (0, -signal.SIGTERM)
        elapsed = time.monotonic() - stopping
        assert 1 <= elapsed < 1 + 3, elapsed
        assert ended.wait(5)
    finally:
        if server.poll() is None:
            server.kill()
            server.wait()
