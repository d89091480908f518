"""The event streams over a real server, the store driven by hand as a worker would drive it, so
that every state change is one the test chose and waits for."""

from __future__ import annotations

import asyncio
import queue
import threading
import time
from collections.abc import Iterator
from typing import Any

import fastapi.routing
import httpx
import pytest

from nanonav.settings import Settings
from nanonav.store import Claim, Outcome
from nanonav.store.migrate import upgrade
from service.app import create_app
from tests.conftest import Api, serve
from tests.service.test_api import assert_problem
from tests.sse import Message, events, messages

WAIT_S = 5.0
STUDY: dict[str, Any] = {
    "name": "two points",
    "base": {"learning": {"episodes": 2, "max_steps": 100}},
    "grid": {"robots.count": [1, 2]},
    "seeds": [0],
}

pytestmark = pytest.mark.timeout(60)


@pytest.fixture
def api_settings(sqlite_url: str) -> Settings:
    return Settings(database_url=sqlite_url, max_body_bytes=64 * 1024, events_poll_s=0.05)


class Reader:
    """Reads one stream in a thread, so the test can change the store and wait for each event."""

    def __init__(self, url: str, path: str, headers: dict[str, str] | None = None) -> None:
        self.received: queue.Queue[Message | None] = queue.Queue()
        self.status_code: int | None = None
        self._client = httpx.Client(base_url=url, timeout=WAIT_S * 2)
        self._thread = threading.Thread(target=self._read, args=(path, headers or {}), daemon=True)
        self._thread.start()

    def _read(self, path: str, headers: dict[str, str]) -> None:
        try:
            with self._client.stream("GET", path, headers=headers) as response:
                self.status_code = response.status_code
                for message in messages(response.iter_lines()):
                    self.received.put(message)
        finally:
            self.received.put(None)
            self._client.close()

    def message(self) -> Message | None:
        """The next block of the stream (event, bare retry or comment); None when it ended."""
        return self.received.get(timeout=WAIT_S)

    def event(self) -> Message | None:
        """The next event with data; None when the stream ended."""
        while (found := self.message()) is not None and found.data is None:
            pass
        return found

    def ended(self) -> bool:
        self._thread.join(timeout=WAIT_S)
        return not self._thread.is_alive()


def submit(api: Api) -> int:
    response = api.client.post("/jobs", json={"learning": {"episodes": 2, "max_steps": 50}})
    assert response.status_code == 202
    job_id: int = response.json()["id"]
    return job_id


def claim(api: Api) -> Claim:
    claimed = api.store.claim("test", lease_s=30)
    assert claimed is not None
    return claimed


def progress(api: Api, claimed: Claim, fraction: float) -> None:
    episodes = claimed.job.episodes
    api.store.report_progress(
        claimed, episode=int(fraction * episodes), episodes=episodes, fraction=fraction, lease_s=30
    )


def finish(api: Api, claimed: Claim) -> None:
    api.store.finish(claimed, Outcome(completed=True, metrics={}, trajectory=None, qtable=None))


def first_event(api: Api, path: str) -> Message:
    with api.client.stream("GET", path) as response:
        return next(events(response))


def test_a_job_stream_sends_its_state_then_every_change_and_ends_when_it_finishes(
    api: Api,
) -> None:
    job_id = submit(api)
    stream = Reader(api.url, f"/jobs/{job_id}/events")
    first = stream.event()
    assert first is not None and stream.status_code == 200
    assert (first.event, first.retry) == ("status", 1000)
    assert first.id is not None and first.id.startswith("queued-")
    assert first.json() == api.client.get(f"/jobs/{job_id}").json()

    claimed = claim(api)
    running = stream.event()
    assert running is not None and running.event == "status"
    assert running.json()["status"] == "running" and running.json()["attempts"] == 1
    for fraction in (0.25, 0.5):
        progress(api, claimed, fraction)
        event = stream.event()
        assert event is not None and event.event == "progress"
        assert event.json()["progress"]["fraction"] == fraction
        assert event.json()["status"] == "running"
    finish(api, claimed)
    last = stream.event()
    assert last is not None and last.event == "status"
    assert last.json() == api.client.get(f"/jobs/{job_id}").json()
    assert last.json()["status"] == "succeeded"
    assert last.id is not None and last.id.startswith("succeeded-")
    assert stream.event() is None and stream.ended()


def test_a_finished_job_stream_sends_its_one_state_and_ends(api: Api) -> None:
    job_id = submit(api)
    api.client.post(f"/jobs/{job_id}/cancel")
    response = api.client.get(f"/jobs/{job_id}/events")
    assert response.status_code == 200
    assert response.headers["content-type"].startswith("text/event-stream")
    sent = list(messages(response.text.splitlines()))
    assert len(sent) == 1
    assert (sent[0].event, sent[0].retry) == ("status", 1000)
    assert sent[0].json() == api.client.get(f"/jobs/{job_id}").json()
    assert sent[0].json()["status"] == "cancelled"


def test_last_event_id_resumes_without_replaying_the_state_the_client_has(api: Api) -> None:
    job_id = submit(api)
    path = f"/jobs/{job_id}/events"
    had = first_event(api, path)
    assert had.id is not None

    resumed = Reader(api.url, path, {"Last-Event-ID": had.id})
    opening = resumed.message()
    assert opening is not None and (opening.retry, opening.data) == (1000, None)
    claimed = claim(api)
    running = resumed.event()
    assert running is not None and running.event == "status" and running.id != had.id
    assert running.json()["status"] == "running"

    progress(api, claimed, 0.5)
    # An older state's id: the current state is sent, as a change of status...
    stale = first_event_with(api, path, had.id)
    assert stale.event == "status" and stale.json()["progress"]["fraction"] == 0.5
    # ...or, from a state of the same status, as progress.
    assert running.id is not None
    assert first_event_with(api, path, running.id).event == "progress"

    finish(api, claimed)
    events_seen = [running]
    while (event := resumed.event()) is not None:
        events_seen.append(event)
    assert had.id not in [e.id for e in events_seen]
    assert events_seen[-1].json()["status"] == "succeeded"
    assert resumed.ended()


def first_event_with(api: Api, path: str, last_event_id: str) -> Message:
    with api.client.stream("GET", path, headers={"Last-Event-ID": last_event_id}) as response:
        return next(events(response))


def test_a_client_that_has_the_final_state_gets_204_and_stops_reconnecting(api: Api) -> None:
    job_id = submit(api)
    api.client.post(f"/jobs/{job_id}/cancel")
    final = first_event(api, f"/jobs/{job_id}/events")
    assert final.id is not None
    again = api.client.get(f"/jobs/{job_id}/events", headers={"Last-Event-ID": final.id})
    assert again.status_code == 204 and again.content == b""


def test_unknown_ids_are_404_problems_before_any_stream(api: Api) -> None:
    assert_problem(api.client.get("/jobs/999/events"), 404)
    assert_problem(api.client.get("/studies/999/events"), 404)
    assert_problem(api.client.get("/jobs/0/events"), 422)
    assert_problem(api.client.get("/studies/abc/events"), 422)


def test_an_idle_stream_gets_keep_alive_comments(api: Api, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(fastapi.routing, "_PING_INTERVAL", 0.2)
    job_id = submit(api)
    stream = Reader(api.url, f"/jobs/{job_id}/events")
    assert stream.event() is not None
    started = time.monotonic()
    ping = stream.message()
    assert ping is not None and (ping.comment, ping.data) == ("ping", None)
    assert time.monotonic() - started < 2
    api.client.post(f"/jobs/{job_id}/cancel")
    last = stream.event()
    assert last is not None and last.json()["status"] == "cancelled"
    assert stream.ended()


@pytest.fixture
def served(sqlite_url: str) -> Iterator[tuple[Api, Any]]:
    """An API whose app the test can look into."""
    upgrade(sqlite_url)
    settings = Settings(database_url=sqlite_url, events_poll_s=0.05)
    app = create_app(settings)
    with serve(app) as url, httpx.Client(base_url=url, timeout=WAIT_S * 2) as client:
        yield Api(url, client, sqlite_url, app.state.store), app


def test_a_client_that_goes_away_stops_being_watched(served: tuple[Api, Any]) -> None:
    api, app = served
    job_id = submit(api)
    channel = app.state.job_events
    with httpx.Client(base_url=api.url, timeout=WAIT_S) as client:
        streams = [client.stream("GET", f"/jobs/{job_id}/events") for _ in range(5)]
        # Kept: a line iterator dropped half-way closes its connection.
        readers = [events(stream.__enter__()) for stream in streams]
        assert all(next(reader).event == "status" for reader in readers)
        until(lambda: channel.listeners == 5)
        for stream in streams:
            stream.__exit__(None, None, None)
    until(lambda: channel.listeners == 0)


def until(condition: Any, timeout: float = WAIT_S) -> None:
    deadline = time.monotonic() + timeout
    while not condition():
        assert time.monotonic() < deadline, "never happened"
        time.sleep(0.02)


def test_a_study_stream_follows_its_jobs_and_ends_when_it_is_done(api: Api) -> None:
    created = api.client.post("/studies", json=STUDY)
    assert created.status_code == 202
    study_id = created.json()["id"]
    stream = Reader(api.url, f"/studies/{study_id}/events")
    first = stream.event()
    assert first is not None and first.event == "status" and first.retry == 1000
    assert first.json() == {
        "id": study_id,
        "status": "queued",
        "jobs": {"total": 2, "queued": 2, "running": 0, "succeeded": 0, "failed": 0,
                 "cancelled": 0},
        "progress": 0.0,
        "finished_at": None,
    }  # fmt: skip

    one = claim(api)
    running = stream.event()
    assert running is not None and running.event == "status"
    assert running.json()["status"] == "running" and running.json()["jobs"]["running"] == 1
    progress(api, one, 0.5)
    halfway = stream.event()
    assert halfway is not None and halfway.event == "progress"
    assert halfway.json()["progress"] == 0.25
    finish(api, one)
    done_one = stream.event()
    assert done_one is not None and done_one.event == "progress"
    assert done_one.json()["jobs"]["succeeded"] == 1 and done_one.json()["progress"] == 0.5
    two = claim(api)
    assert stream.event() is not None  # the second job running
    finish(api, two)
    last = stream.event()
    assert last is not None and last.event == "status"
    whole = api.client.get(f"/studies/{study_id}").json()
    state = last.json()
    assert state["status"] == whole["status"] == "succeeded"
    assert state["jobs"] == whole["jobs"]
    assert state["progress"] == whole["progress"] == 1.0
    assert state["finished_at"] == whole["finished_at"] is not None
    assert stream.event() is None and stream.ended()


def test_streams_are_503_while_the_poller_is_not_running(sqlite_url: str) -> None:
    upgrade(sqlite_url)
    app = create_app(Settings(database_url=sqlite_url))  # served without its lifespan

    async def ask() -> list[httpx.Response]:
        transport = httpx.ASGITransport(app=app)
        async with httpx.AsyncClient(transport=transport, base_url="http://testserver") as client:
            job_id = (await client.post("/jobs", json={})).json()["id"]
            study_id = (await client.post("/studies", json=STUDY)).json()["id"]
            return [
                await client.get(f"/jobs/{job_id}/events"),
                await client.get(f"/studies/{study_id}/events"),
            ]

    try:
        for response in asyncio.run(ask()):
            assert_problem(response, 503)
            assert response.headers["retry-after"] == "1"
    finally:
        app.state.store.close()
