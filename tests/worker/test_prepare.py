"""A worker compiles the engine in a process of its own before it claims a job, saying all
along that it is alive and preparing: the compile goes with the worker (a stop ends it, and
so does a kill), and once a worker was ready on a cache the next one loads from it without
that process."""

from __future__ import annotations

import signal
import subprocess
import threading
import time
from pathlib import Path
from typing import Any, ClassVar

import pytest

import worker.loop as loop
from nanonav.store import JobStore
from nanonav.store.migrate import upgrade
from tests.conftest import sqlite_url_in
from tests.processes import Worker, child_of, gone

pytestmark = pytest.mark.timeout(120)


def compiling_worker(tmp_path: Path, name: str) -> tuple[Worker, int]:
    """A ``python -m worker`` on an empty cache of its own, and its compiling process."""
    cache = tmp_path / "cache"
    url = sqlite_url_in(tmp_path)
    upgrade(url)
    worker = Worker(url, tmp_path / f"{name}.log", NUMBA_CACHE_DIR=str(cache))
    return worker, child_of(worker.process.pid, b"compile_alone")


def test_a_worker_compiling_is_preparing_and_a_stop_ends_the_compile_and_the_worker(
    tmp_path: Path,
) -> None:
    worker, compiling = compiling_worker(tmp_path, "stopped")
    store = JobStore.from_url(sqlite_url_in(tmp_path))
    try:
        deadline = time.monotonic() + 30
        while (census := store.census(seen_within_s=30)).preparing == 0:
            assert time.monotonic() < deadline, "the worker never said it was preparing"
            time.sleep(0.1)
        assert census.workers == 0
        assert worker.terminate(timeout=20) == 0
        assert gone(compiling)
        census = store.census(seen_within_s=30)
        assert (census.workers, census.preparing) == (0, 0)  # it is forgotten
    finally:
        store.close()
    assert "stopped before the engine was ready" in worker.text()
    assert " ready on " not in worker.text()


def test_a_killed_workers_compile_dies_with_it(tmp_path: Path) -> None:
    worker, compiling = compiling_worker(tmp_path, "killed")
    worker.process.send_signal(signal.SIGKILL)
    worker.process.wait()
    worker.terminate()
    assert gone(compiling)


class _Compiled:
    """What ``subprocess.Popen`` gives ``prepare``: a process that compiled, at once."""

    started: ClassVar[list[list[str]]] = []
    returncode = 0

    def __init__(self, command: list[str], **_: Any) -> None:
        self.started.append(command)

    def poll(self) -> int:
        return self.returncode


def test_a_worker_ready_on_a_cache_leaves_the_next_no_compile(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    loaded: list[int] = []
    monkeypatch.setattr(loop, "CACHE", tmp_path)
    monkeypatch.setattr(loop, "warm_up", lambda: loaded.append(1))
    monkeypatch.setattr(subprocess, "Popen", _Compiled)  # the module loop.subprocess is
    _Compiled.started.clear()
    assert loop.prepare(threading.Event())
    assert len(_Compiled.started) == 1 and "compile_alone" in _Compiled.started[0][-1]
    assert loop.prepare(threading.Event())  # the cache was made ready by the first
    assert len(_Compiled.started) == 1 and len(loaded) == 2
    for mark in tmp_path.glob("worker-ready-*"):  # a cache another worker's warm-up made
        mark.rename(tmp_path / "worker-ready-000000000000")
    assert loop.prepare(threading.Event())
    assert len(_Compiled.started) == 2
