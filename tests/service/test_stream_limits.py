"""Event streams per caller and per API process, over real sockets: past either limit a stream
is refused with 503 and Retry-After before it starts, and a closed stream frees its place."""

from __future__ import annotations

import socket
import time
from collections.abc import Iterator
from contextlib import ExitStack, closing, contextmanager
from typing import Any

import httpx
import pytest

from nanonav.settings import Settings
from nanonav.store.migrate import upgrade
from service.app import create_app
from tests import raw_http as raw
from tests.conftest import SCRIPTED, serve

KEY_A = "streams-a-7Hq2Wd9Lx4Nv6Tb1Kz8Rp3Ys5Mf0Gc"
KEY_B = "streams-b-3Jt8Vn1Qw5Zx7Lk2Hd9Cs4Bm6Fy0Pr"
STUDY: dict[str, Any] = {
    "name": "two points",
    "base": {"learning": {"episodes": 1, "max_steps": 30}},
    "grid": {"robots.count": [1, 2]},
    "seeds": [0],
}

pytestmark = pytest.mark.timeout(60)


@contextmanager
def served(sqlite_url: str, per_key: int, per_process: int, keys: bool) -> Iterator[str]:
    upgrade(sqlite_url)
    settings = Settings(
        database_url=sqlite_url,
        api_keys=f"{KEY_A},{KEY_B}" if keys else "",
        events_streams_per_key=per_key,
        events_streams_per_process=per_process,
    )
    with serve(create_app(settings)) as url:
        yield url


def auth(key: str | None) -> dict[str, str]:
    return {"Authorization": f"Bearer {key}"} if key else {}


def submit(url: str, key: str | None, path: str = "/jobs", body: Any = None) -> int:
    """A job (or study) of ``key``'s; with no worker it stays queued, its stream open."""
    headers = {**auth(key), **SCRIPTED}
    response = httpx.post(f"{url}{path}", json=body or {}, headers=headers)
    assert response.status_code == 202, response.text
    found: int = response.json()["id"]
    return found


class Streams:
    """Event streams held open on raw connections, each closed when the test is done."""

    def __init__(self, url: str, stack: ExitStack) -> None:
        self.url = url
        self.stack = stack
        self.last: socket.socket | None = None  # the connection of the last stream opened

    def open(self, path: str, key: str | None = None, source: str | None = None) -> raw.Answer:
        """Ask for a stream; a 200's connection stays open, anything else is read whole."""
        sock = self.stack.enter_context(closing(raw.connect(self.url, source)))
        sock.sendall(raw.head("GET", path, auth(key)))
        answer = raw.read_head(sock)
        if answer.status != 200:
            return raw.read_answer_rest(sock, answer)
        self.last = sock
        return answer


def assert_refused(answer: raw.Answer, mentions: str) -> None:
    assert answer.status == 503, answer
    assert answer.headers["content-type"] == "application/problem+json"
    assert int(answer.headers["retry-after"]) >= 1
    problem = answer.json()
    assert problem["status"] == 503
    assert problem["type"].endswith("too-many-streams")
    assert mentions in problem["detail"], problem["detail"]


def reopens(streams: Streams, path: str, key: str | None, within_s: float = 3.0) -> bool:
    """Whether a stream on ``path`` opens again (its freed place noticed) within ``within_s``."""
    deadline = time.monotonic() + within_s
    while time.monotonic() < deadline:
        if streams.open(path, key).status == 200:
            return True
        time.sleep(0.05)
    return False


def test_a_key_past_its_streams_gets_503_while_another_key_gets_its_stream(
    sqlite_url: str,
) -> None:
    with served(sqlite_url, per_key=2, per_process=100, keys=True) as url, ExitStack() as stack:
        job_a, job_b = submit(url, KEY_A), submit(url, KEY_B)
        streams = Streams(url, stack)
        assert streams.open(f"/jobs/{job_a}/events", KEY_A).status == 200
        assert streams.open(f"/jobs/{job_a}/events", KEY_A).status == 200
        held = streams.last
        assert held is not None
        assert_refused(streams.open(f"/jobs/{job_a}/events", KEY_A), "2 event streams")
        study_a = submit(url, KEY_A, "/studies", STUDY)
        assert_refused(streams.open(f"/studies/{study_a}/events", KEY_A), "2 event streams")
        assert streams.open(f"/jobs/{job_b}/events", KEY_B).status == 200
        held.close()
        assert reopens(streams, f"/studies/{study_a}/events", KEY_A)


def test_without_keys_streams_are_counted_per_client_address(sqlite_url: str) -> None:
    with served(sqlite_url, per_key=1, per_process=100, keys=False) as url, ExitStack() as stack:
        job = submit(url, None)
        streams = Streams(url, stack)
        path = f"/jobs/{job}/events"
        assert streams.open(path, source="127.0.0.1").status == 200
        assert_refused(streams.open(path, source="127.0.0.1"), "1 event streams")
        assert streams.open(path, source="127.0.0.2").status == 200


def test_a_process_past_its_streams_refuses_every_key(sqlite_url: str) -> None:
    with served(sqlite_url, per_key=10, per_process=3, keys=True) as url, ExitStack() as stack:
        job_a, job_b = submit(url, KEY_A), submit(url, KEY_B)
        study_b = submit(url, KEY_B, "/studies", STUDY)
        streams = Streams(url, stack)
        assert streams.open(f"/jobs/{job_a}/events", KEY_A).status == 200
        assert streams.open(f"/jobs/{job_b}/events", KEY_B).status == 200
        assert streams.open(f"/studies/{study_b}/events", KEY_B).status == 200
        held = streams.last
        assert held is not None
        assert_refused(streams.open(f"/jobs/{job_a}/events", KEY_A), "3 event streams")
        assert_refused(streams.open(f"/jobs/{job_b}/events", KEY_B), "3 event streams")
        held.close()
        assert reopens(streams, f"/jobs/{job_a}/events", KEY_A)
        assert_refused(streams.open(f"/jobs/{job_b}/events", KEY_B), "3 event streams")


def test_a_finished_jobs_stream_gives_its_place_back(sqlite_url: str) -> None:
    with served(sqlite_url, per_key=1, per_process=100, keys=True) as url:
        job = submit(url, KEY_A)
        headers = {**auth(KEY_A), **SCRIPTED}
        assert httpx.post(f"{url}/jobs/{job}/cancel", headers=headers).status_code == 200
        for _ in range(3):  # one event, the end, and its place is free for the next
            with httpx.stream("GET", f"{url}/jobs/{job}/events", headers=headers) as response:
                assert response.status_code == 200
                assert "cancelled" in response.read().decode()
