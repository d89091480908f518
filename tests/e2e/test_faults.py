"""Workers that die: a killed worker's job runs again within 20 s, even while the other worker
is busy; workers and API processes under a supervisor that dies stop too."""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from nanonav.store.migrate import upgrade
from tests.conftest import Api
from tests.processes import Worker, clean_environment, free_port

pytestmark = pytest.mark.timeout(120)

# Random walkers in a big cube: every episode runs its full length, for minutes in all.
LONG: dict[str, Any] = {"space": {"size": 1000}, "robots": {"count": 50, "policy": "random"},
                        "learning": {"episodes": 900, "max_steps": 20_000}}  # fmt: skip


def wait_until(condition: Callable[[], bool], timeout: float, what: str) -> None:
    deadline = time.monotonic() + timeout
    while not condition():
        assert time.monotonic() < deadline, what
        time.sleep(0.1)


def gone(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return True
    # a child that exited but is not yet reaped by init shows as a zombie
    with open(f"/proc/{pid}/stat") as stat:
        return stat.read().split()[2] == "Z"


def test_a_killed_workers_job_runs_again_within_20_s_while_the_other_is_busy(
    api: Api, start_worker: Callable[..., Worker]
) -> None:
    first, second = start_worker(), start_worker()
    first.wait_ready()
    second.wait_ready()
    jobs = [api.client.post("/jobs", json={**LONG, "seed": s}).json()["id"] for s in range(2)]
    wait_until(lambda: all(api.store.get(j).status.value == "running" for j in jobs), 30,
               "both jobs did not start")  # fmt: skip
    victim = next(j for j in jobs if f"job {j}: claimed" in first.text())
    first.process.send_signal(signal.SIGKILL)
    first.process.wait()
    killed = time.monotonic()
    # the second worker is busy with its own long job: the sweep must not wait for it
    replacement = start_worker()
    wait_until(lambda: api.store.get(victim).attempts == 2, 25, "the job was never run again")
    assert time.monotonic() - killed < 20
    assert api.store.get(victim).status.value == "running"
    for job in jobs:
        api.client.post(f"/jobs/{job}/cancel")
    assert replacement.process.poll() is None


def test_workers_stop_when_their_supervisor_dies(
    api: Api, start_worker: Callable[..., Worker]
) -> None:
    supervisor = start_worker("--concurrency", "2")
    wait_until(lambda: len(re.findall(r"worker (\d+) ready", supervisor.text())) == 2, 90,
               "the children did not start")  # fmt: skip
    children = [int(pid) for pid in re.findall(r"worker (\d+) ready", supervisor.text())]
    supervisor.process.send_signal(signal.SIGKILL)
    supervisor.process.wait()
    wait_until(lambda: all(gone(pid) for pid in children), 15, "orphaned workers kept running")


def test_api_processes_stop_when_their_supervisor_dies(sqlite_url: str, tmp_path: Path) -> None:
    upgrade(sqlite_url)
    log_path = tmp_path / "api.log"
    children: list[int] = []
    nanonav = str(Path(sys.executable).with_name("nanonav"))
    command = [nanonav, "api", "--port", str(free_port()), "--processes", "2"]
    with log_path.open("wb") as log:
        supervisor = subprocess.Popen(command, env=clean_environment(
            DATABASE_URL=sqlite_url), stdout=log, stderr=subprocess.STDOUT)  # fmt: skip
    try:
        wait_until(lambda: log_path.read_text().count("Application startup complete") == 2, 90,
                   "the API processes did not start")  # fmt: skip
        started = re.findall(r"Started server process \[(\d+)\]", log_path.read_text())
        children += [int(pid) for pid in started]
        assert len(children) == 2
        supervisor.send_signal(signal.SIGKILL)
        supervisor.wait()
        wait_until(lambda: all(gone(pid) for pid in children), 15,
                   "orphaned API processes kept serving")  # fmt: skip
        assert log_path.read_text().count("Application shutdown complete") == 2
    finally:
        if supervisor.poll() is None:
            supervisor.kill()
            supervisor.wait()
        for pid in children:
            if not gone(pid):
                os.kill(pid, signal.SIGKILL)
