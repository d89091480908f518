"""Slow clients and too many connections, over real sockets against a real served API: a request
head or body that does not arrive in time is cut off with 408, connections past the limit get
503 while ``/healthz`` still answers, and the limit must fit the process's open files."""

from __future__ import annotations

import json
import subprocess
import sys
import time
from collections.abc import Iterator
from contextlib import closing, contextmanager

import httpx
import pytest

from nanonav.settings import Settings
from nanonav.store.migrate import upgrade
from service.app import create_app
from tests import raw_http as raw
from tests.conftest import SCRIPTED, Api, serve
from tests.processes import clean_environment, free_port
from tests.sse import events

HEAD_S = 1.0
BODY_S = 1.0
# How much later than its timeout a connection may be closed: the timer, the loop, the machine.
SLACK_S = 1.0
PROBLEM = "application/problem+json"

pytestmark = pytest.mark.timeout(60)


@pytest.fixture
def api_settings(sqlite_url: str) -> Settings:
    return Settings(
        database_url=sqlite_url,
        max_body_bytes=64 * 1024,
        api_header_timeout_s=HEAD_S,
        api_body_timeout_s=BODY_S,
    )


def assert_408(closed: raw.Closed, within_s: float) -> None:
    assert closed.after_s is not None, "the connection is still open"
    assert within_s - 0.2 <= closed.after_s < within_s + SLACK_S, closed.after_s
    answer = raw.parse(closed.received)
    assert answer.status == 408
    assert answer.headers["content-type"] == PROBLEM
    assert answer.headers["connection"] == "close"
    assert answer.json()["status"] == 408


def test_a_request_head_sent_a_line_at_a_time_is_cut_off_with_408(api: Api) -> None:
    with closing(raw.connect(api.url)) as sock:
        lines = [b"GET /healthz HTTP/1.1\r\n", *[b"X-Slow: 1\r\n"] * 20]
        closed = raw.trickle(sock, lines, every_s=0.2, limit_s=HEAD_S + 4)
    assert_408(closed, HEAD_S)


def test_a_connection_that_says_nothing_is_closed_and_told_nothing(api: Api) -> None:
    with closing(raw.connect(api.url)) as sock:
        closed = raw.trickle(sock, [], every_s=1, limit_s=HEAD_S + 4)
    assert closed.after_s is not None, "the silent connection is still open"
    assert HEAD_S - 0.2 <= closed.after_s < HEAD_S + SLACK_S
    assert closed.received == b""


def test_a_trickling_body_is_cut_off_with_408_and_nothing_is_submitted(api: Api) -> None:
    headers = {"Content-Type": "application/json", "Content-Length": "200", **SCRIPTED}
    with closing(raw.connect(api.url)) as sock:
        sock.sendall(raw.head("POST", "/jobs", headers))
        closed = raw.trickle(sock, [b" "] * 100, every_s=0.1, limit_s=BODY_S + 4)
    assert_408(closed, BODY_S)
    assert api.client.get("/jobs").json()["jobs"] == []


def test_a_body_sent_in_pieces_within_the_timeout_is_served(api: Api) -> None:
    body = b"{}".ljust(120)
    headers = {"Content-Type": "application/json", "Content-Length": str(len(body))}
    with closing(raw.connect(api.url)) as sock:
        sock.sendall(raw.head("POST", "/jobs", headers))
        for start in range(0, len(body), 30):
            time.sleep(BODY_S / 6)
            sock.sendall(body[start : start + 30])
        answer = raw.read_answer(sock)
    assert answer.status == 202, answer.body
    assert [job["id"] for job in api.client.get("/jobs").json()["jobs"]] == [answer.json()["id"]]


def test_each_request_of_a_kept_alive_connection_gets_its_own_header_time(api: Api) -> None:
    """The timer starts at a request's first byte: a connection older than the timeout whose
    next request arrives promptly is served."""
    with closing(raw.connect(api.url)) as sock:
        sock.sendall(raw.head("GET", "/healthz"))
        assert raw.read_answer(sock).status == 200
        time.sleep(HEAD_S * 0.7)
        request = raw.head("GET", "/version")
        sock.sendall(request[:10])
        time.sleep(HEAD_S * 0.6)
        sock.sendall(request[10:])
        answer = raw.read_answer(sock)
    assert answer.status == 200
    assert answer.json()["version"]


def test_an_event_stream_outlives_the_header_and_body_timeouts(api: Api) -> None:
    job_id = api.client.post("/jobs", json={}).json()["id"]  # no worker: it stays queued
    with api.client.stream("GET", f"/jobs/{job_id}/events") as response:
        seen = events(response)
        assert next(seen).json()["status"] == "queued"
        time.sleep(HEAD_S + BODY_S + 0.5)
        assert api.client.post(f"/jobs/{job_id}/cancel").status_code == 200
        assert next(seen).json()["status"] == "cancelled"


@contextmanager
def limited(sqlite_url: str, connections: int, reserve: int) -> Iterator[str]:
    """An API process that serves ``connections`` connections, and ``reserve`` more for
    /healthz alone; connections that say nothing stay open for the test's length."""
    upgrade(sqlite_url)
    settings = Settings(
        database_url=sqlite_url,
        api_max_connections=connections,
        api_healthz_connections=reserve,
        api_header_timeout_s=30,
    )
    with serve(create_app(settings)) as url:
        yield url


@contextmanager
def streams(url: str, count: int) -> Iterator[None]:
    """``count`` connections kept busy, each with an event stream of a queued job."""
    job_id = httpx.post(f"{url}/jobs", json={}).json()["id"]  # no worker: it stays queued
    with raw.connections(url, count) as busy:
        for sock in busy:
            sock.sendall(raw.head("GET", f"/jobs/{job_id}/events"))
            assert raw.read_head(sock).status == 200
        yield


def settle() -> None:
    """Give the server time to accept the connections just opened."""
    time.sleep(0.3)


def test_connections_past_the_limit_get_503_while_healthz_still_answers(sqlite_url: str) -> None:
    with limited(sqlite_url, connections=4, reserve=2) as url:
        with streams(url, 4):
            refused = raw.ask(url, "GET", "/jobs")
            assert refused.status == 503
            assert refused.headers["content-type"] == PROBLEM
            assert refused.headers["retry-after"] == "1"
            assert refused.headers["connection"] == "close"
            assert refused.json()["status"] == 503
            assert "NANONAV_API_MAX_CONNECTIONS" in refused.json()["detail"]
            health = raw.ask(url, "GET", "/healthz")
            assert health.status == 200
            assert health.json()["status"] == "ok"
        settle()
        assert httpx.get(f"{url}/jobs").status_code == 200


def test_a_healthz_connection_past_the_limit_answers_once_and_closes(sqlite_url: str) -> None:
    with (
        limited(sqlite_url, connections=2, reserve=1) as url,
        streams(url, 2),
        closing(raw.connect(url)) as sock,
    ):
        sock.sendall(raw.head("GET", "/healthz"))
        answer = raw.read_answer(sock)
        assert answer.status == 200
        assert answer.headers["connection"] == "close"
        assert raw.is_closed(sock, within_s=2)


def test_a_new_connection_takes_the_place_of_the_one_idle_longest(sqlite_url: str) -> None:
    """Every place held by a connection that said nothing: the next one is served in the
    place of the oldest, so slow clients cannot keep others out."""
    with limited(sqlite_url, connections=4, reserve=2) as url, raw.connections(url, 4) as idle:
        time.sleep(1.2)  # idle for more than a second: slow, not a burst of new clients
        answer = raw.ask(url, "GET", "/jobs")
        assert answer.status == 200
        assert answer.json()["jobs"] == []
        assert raw.is_closed(idle[0], within_s=2)
        assert not any(raw.is_closed(sock, within_s=0.1) for sock in idle[1:])


def nanonav_api_with_open_files(soft: int, hard: int, port: int) -> list[str]:
    """``nanonav api`` in a process whose open-file limit is ``soft``/``hard``."""
    code = (
        "import resource, sys; "
        f"resource.setrlimit(resource.RLIMIT_NOFILE, ({soft}, {hard})); "
        "from nanonav.cli import main; "
        f"sys.exit(main(['api', '--port', '{port}']))"
    )
    return [sys.executable, "-c", code]


def test_a_connection_limit_the_open_files_cannot_hold_is_refused_at_start_up(
    sqlite_url: str,
) -> None:
    upgrade(sqlite_url)
    env = clean_environment(DATABASE_URL=sqlite_url, NANONAV_API_MAX_CONNECTIONS="1000")
    command = nanonav_api_with_open_files(512, 512, free_port())
    done = subprocess.run(command, env=env, capture_output=True, text=True, timeout=30)
    assert done.returncode == 2, done.stderr
    assert "NANONAV_API_MAX_CONNECTIONS" in done.stderr
    assert "512" in done.stderr


def test_the_soft_open_file_limit_is_raised_to_fit_the_connections() -> None:
    code = (
        "import json, resource; "
        "resource.setrlimit(resource.RLIMIT_NOFILE, (256, 4096)); "
        "from nanonav.settings import Settings; "
        "from service.server import server_config; "
        "server_config('service.app:create_app', Settings(api_max_connections=1000), "
        "factory=True); "
        "print(json.dumps(resource.getrlimit(resource.RLIMIT_NOFILE)))"
    )
    done = subprocess.run([sys.executable, "-c", code], env=clean_environment(),
                          capture_output=True, text=True, timeout=30)  # fmt: skip
    assert done.returncode == 0, done.stderr
    soft, hard = json.loads(done.stdout.splitlines()[-1])
    assert hard == 4096
    assert 1000 < soft <= 4096
