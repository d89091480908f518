"""Real ``python -m worker`` processes for the end-to-end tests, stopped after each test."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

from tests.conftest import Api
from tests.processes import Worker


@pytest.fixture
def start_worker(api: Api, tmp_path: Path) -> Iterator[Callable[..., Worker]]:
    workers: list[Worker] = []

    def start(*args: str, **env: str) -> Worker:
        worker = Worker(api.database_url, tmp_path / f"worker-{len(workers)}.log", *args, **env)
        workers.append(worker)
        return worker

    yield start
    for worker in workers:
        worker.terminate()  # also closes the log of one that has already exited
