"""A worker frozen in any phase of a job (SIGSTOP, as a paused VM or a swapped-out process is)
never stalls the API's writes on SQLite between its transactions: it holds no lock then, so
submits, studies and cancels answer at once while it is frozen, and its jobs go on when it is
continued. Frozen inside one of its (short) write transactions, it holds SQLite's write lock
until it runs again: the test sees that from the lock itself and freezes it again a moment later;
benchmarks/write_locks.py measures how much of the time that window is open."""

from __future__ import annotations

import os
import signal
import sqlite3
import time
from collections.abc import Callable, Iterator
from concurrent.futures import ThreadPoolExecutor
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import httpx
import pytest

from tests.conftest import SCRIPTED, api_and_worker
from tests.processes import Worker

pytestmark = pytest.mark.timeout(240)
# Half the 30 s that a write waits for SQLite's lock before it gives up with 503, and far more
# than a write takes on two cores shared by the test processes.
ANSWER_S = 15.0
# Freezes that may land inside one of the worker's transactions before the test gives up: each
# such window is milliseconds long, so two in a row are already rare.
TRIES = 20
TINY: dict[str, Any] = {"robots": {"count": 2}, "learning": {"episodes": 1, "max_steps": 20}}
# Long enough (tens of seconds on a busy machine) to be frozen mid-run, with progress written.
LONG: dict[str, Any] = {
    "preset": "tumour-microswimmers",
    "robots": {"count": 20},
    "learning": {"episodes": 40},
}


def write_lock_free(database: str) -> bool:
    """Whether a write transaction on ``database`` (a SQLite URL) begins within a moment."""
    connection = sqlite3.connect(database.removeprefix("sqlite:///"), timeout=0.5)
    try:
        connection.execute("BEGIN IMMEDIATE")
        connection.rollback()
        return True
    except sqlite3.OperationalError:
        return False
    finally:
        connection.close()


@contextmanager
def frozen(worker: Worker, database: str) -> Iterator[None]:
    """The worker stopped at a moment it holds no transaction."""
    for _ in range(TRIES):
        os.kill(worker.process.pid, signal.SIGSTOP)
        if write_lock_free(database):
            break
        os.kill(worker.process.pid, signal.SIGCONT)
        time.sleep(0.01)
    else:
        pytest.fail(f"the worker held SQLite's write lock at {TRIES} freezes in a row")
    try:
        yield
    finally:
        os.kill(worker.process.pid, signal.SIGCONT)


def writes_answer_at_once(url: str) -> None:
    """A submit, then eight more, a study and the first one's cancel sent together: each answers
    within ANSWER_S."""
    with httpx.Client(base_url=url, timeout=ANSWER_S, headers=SCRIPTED) as client:
        cancel_id = client.post("/jobs", json=TINY).json()["id"]
        sends: list[Callable[[], httpx.Response]] = [
            *(lambda s=s: client.post("/jobs", json={**TINY, "seed": s}) for s in range(8)),
            lambda: client.post("/studies", json={"base": TINY, "seeds": [1, 2, 3]}),
            lambda: client.post(f"/jobs/{cancel_id}/cancel"),
        ]
        with ThreadPoolExecutor(len(sends)) as pool:
            answers = [future.result() for future in [pool.submit(send) for send in sends]]
    assert [a.status_code for a in answers] == [202] * 9 + [200], [a.text for a in answers]


def wait_for(read: Callable[[], bool], what: str, timeout_s: float = 120.0) -> None:
    deadline = time.monotonic() + timeout_s
    while not read():
        assert time.monotonic() < deadline, f"never saw {what}"
        time.sleep(0.01)


def test_a_worker_frozen_in_any_phase_never_stalls_the_api_s_writes(tmp_path: Path) -> None:
    with (
        api_and_worker(tmp_path) as (api, worker, database),
        httpx.Client(base_url=api.url, timeout=30, headers=SCRIPTED) as client,
    ):
        phases = []

        def job(job_id: int) -> dict[str, Any]:
            answer: dict[str, Any] = client.get(f"/jobs/{job_id}").json()
            return answer

        # idle: waiting for work, between polls of the queue
        with frozen(worker, database):
            writes_answer_at_once(api.url)
        phases.append("idle")

        # claimed: the job is running, no progress written yet; then mid-run
        target = client.post("/jobs", json=LONG).json()["id"]
        for phase, seen in (
            ("claimed", lambda: job(target)["status"] == "running"),
            ("running", lambda: 0.05 < job(target)["progress"]["fraction"] < 0.9),
        ):
            wait_for(seen, phase)
            with frozen(worker, database):
                writes_answer_at_once(api.url)
            phases.append(phase)
        assert client.post(f"/jobs/{target}/cancel").status_code == 200
        wait_for(lambda: job(target)["status"] == "cancelled", "the cancel honoured")

        # finished: the result just stored, nothing left to claim
        def drained() -> bool:
            return all(
                client.get(f"/jobs?status={status}").json()["jobs"] == []
                for status in ("queued", "running")
            )

        wait_for(drained, "the queue drained", timeout_s=180)
        last = client.post("/jobs", json=TINY).json()["id"]
        wait_for(lambda: job(last)["status"] == "succeeded", "finished")
        with frozen(worker, database):
            writes_answer_at_once(api.url)
        phases.append("finished")
        # continued, the worker runs everything that was queued meanwhile
        wait_for(drained, "the queue drained", timeout_s=180)
    assert phases == ["idle", "claimed", "running", "finished"]
