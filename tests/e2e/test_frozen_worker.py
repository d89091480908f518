"""A worker frozen in any phase of a job (SIGSTOP, as a paused VM or a swapped-out process is)
never stalls the API's writes on SQLite: it holds no transaction between its writes, each of
which is short (benchmarks/write_locks.py measures how short), so submits, studies and cancels
answer at once while it is frozen, and its job goes on when it is continued."""

from __future__ import annotations

import os
import signal
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
# Far below the 30 s that a write waits for SQLite's lock before it gives up with 503.
ANSWER_S = 5.0
TINY: dict[str, Any] = {"robots": {"count": 2}, "learning": {"episodes": 1, "max_steps": 20}}
# Long enough (tens of seconds on a busy machine) to be frozen mid-run, with progress written.
LONG: dict[str, Any] = {
    "preset": "tumour-microswimmers",
    "robots": {"count": 20},
    "learning": {"episodes": 40},
}


@contextmanager
def frozen(worker: Worker) -> Iterator[None]:
    os.kill(worker.process.pid, signal.SIGSTOP)
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
        api_and_worker(tmp_path) as (api, worker, _),
        httpx.Client(base_url=api.url, timeout=30, headers=SCRIPTED) as client,
    ):
        phases = []

        def job(job_id: int) -> dict[str, Any]:
            answer: dict[str, Any] = client.get(f"/jobs/{job_id}").json()
            return answer

        # idle: waiting for work, between polls of the queue
        with frozen(worker):
            writes_answer_at_once(api.url)
        phases.append("idle")

        # claimed: the job is running, no progress written yet; then mid-run
        target = client.post("/jobs", json=LONG).json()["id"]
        for phase, seen in (
            ("claimed", lambda: job(target)["status"] == "running"),
            ("running", lambda: 0.05 < job(target)["progress"]["fraction"] < 0.9),
        ):
            wait_for(seen, phase)
            with frozen(worker):
                writes_answer_at_once(api.url)
            phases.append(phase)
        assert client.post(f"/jobs/{target}/cancel").status_code == 200
        wait_for(lambda: job(target)["status"] == "cancelled", "the cancel honoured")

        # finishing: the result just stored, the worker drawing nothing yet or claiming again
        last = client.post("/jobs", json=TINY).json()["id"]
        wait_for(lambda: job(last)["status"] == "succeeded", "finished")
        with frozen(worker):
            writes_answer_at_once(api.url)
        phases.append("finished")
        # continued, the worker runs everything that was queued meanwhile
        wait_for(
            lambda: (
                client.get("/jobs?status=queued").json()["jobs"] == []
                and client.get("/jobs?status=running").json()["jobs"] == []
            ),
            "the queue drained",
            timeout_s=180,
        )
    assert phases == ["idle", "claimed", "running", "finished"]
