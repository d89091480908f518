"""Real ``python -m worker`` processes for the end-to-end tests, stopped after each test."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

from tests.conftest import Api

# The first job of a fresh worker may wait for numba to compile (or load) the engine's kernels.
FIRST_JOB_S = 120.0


class Worker:
    """A ``python -m worker`` process whose log goes to a file."""

    def __init__(self, database_url: str, log: Path, *args: str, **env: str) -> None:
        self.log = log
        environment = {**os.environ, "NANONAV_DATABASE_URL": database_url, **env}
        environment.setdefault("NANONAV_POLL_INTERVAL_S", "0.05")
        self._log_file = log.open("wb")
        self.process = subprocess.Popen(
            [sys.executable, "-m", "worker", *args],
            env=environment,
            stdout=self._log_file,
            stderr=subprocess.STDOUT,
        )

    def terminate(self, timeout: float = 20.0) -> int:
        if self.process.poll() is None:
            self.process.send_signal(signal.SIGTERM)
        try:
            code = self.process.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            self.process.kill()
            self.process.wait()
            raise
        finally:
            self._log_file.close()
        return code

    def text(self) -> str:
        return self.log.read_text()

    def wait_ready(self, timeout: float = FIRST_JOB_S) -> None:
        """Until the worker has loaded the engine and looks at the queue."""
        deadline = time.monotonic() + timeout
        while " ready on " not in self.text():
            assert self.process.poll() is None, self.text()
            assert time.monotonic() < deadline, "the worker did not get ready"
            time.sleep(0.05)


@pytest.fixture
def start_worker(api: Api, tmp_path: Path) -> Iterator[Callable[..., Worker]]:
    workers: list[Worker] = []

    def start(*args: str, **env: str) -> Worker:
        worker = Worker(api.database_url, tmp_path / f"worker-{len(workers)}.log", *args, **env)
        workers.append(worker)
        return worker

    yield start
    for worker in workers:
        if worker.process.poll() is None:
            worker.terminate()
