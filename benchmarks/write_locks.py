"""How long a worker holds SQLite's write lock, and so how likely a worker frozen at a random
moment (SIGSTOP, a paused VM) is to stall every API write until it is continued.

    python benchmarks/write_locks.py            # three jobs of each scenario (about a minute)
    python benchmarks/write_locks.py --quick    # one small job each

Each job is claimed, run and stored here as a worker does (``worker.job.run_job``, with its
heartbeat thread), on a real SQLite file. A transaction holds the write lock from its first
write (or its ``BEGIN IMMEDIATE``) to its commit; the table gives, per kind of transaction and
thread, how many there were and the longest, and the share of the jobs' wall time spent holding
the lock: the chance that a freeze at a random moment lands inside a transaction. Between
transactions the worker holds nothing (tests/e2e/test_frozen_worker.py freezes it there).
"""

from __future__ import annotations

import argparse
import tempfile
import threading
import time
from collections import defaultdict
from pathlib import Path
from typing import Any

from sqlalchemy import event

from nanonav.settings import Settings
from nanonav.store import JobStore
from nanonav.store.migrate import upgrade
from worker.job import run_job

WRITES = ("INSERT", "UPDATE", "DELETE", "BEGIN IMMEDIATE")
SCENARIOS: dict[str, dict[str, Any]] = {
    "paper-swarm": {"preset": "paper-swarm"},
    "tumour-microswimmers": {"preset": "tumour-microswimmers"},
}
QUICK: dict[str, Any] = {"learning": {"episodes": 2}}


class LockClock:
    """Times, per connection, from the first write of a transaction to its end."""

    def __init__(self, store: JobStore) -> None:
        self.held: dict[str, list[float]] = defaultdict(list)
        self._open: dict[int, tuple[float, str]] = {}
        event.listen(store.engine, "before_cursor_execute", self._statement)
        event.listen(store.engine, "commit", self._end)
        event.listen(store.engine, "rollback", self._end)

    def _statement(self, conn: Any, cursor: Any, statement: str, *args: Any) -> None:
        words = statement.split()
        if id(conn) in self._open:
            start, kind = self._open[id(conn)]
            if kind.startswith("BEGIN IMMEDIATE") and kind.count(" ") < 3:
                self._open[id(conn)] = (start, f"{kind} {' '.join(words[:3])}")
            return
        if statement.lstrip().upper().startswith(WRITES):
            thread = threading.current_thread().name.split("-")[0]
            kind = " ".join(words[:2] if words[0] == "BEGIN" else words[:3])
            self._open[id(conn)] = (time.perf_counter(), f"{kind} [{thread}]")

    def _end(self, conn: Any) -> None:
        opened = self._open.pop(id(conn), None)
        if opened is not None:
            self.held[opened[1]].append(time.perf_counter() - opened[0])


def measure(scenario: dict[str, Any], jobs: int) -> tuple[dict[str, list[float]], float]:
    """The write-lock holds of ``jobs`` runs of ``scenario``, and their wall time, s."""
    with tempfile.TemporaryDirectory() as directory:
        url = f"sqlite:///{Path(directory) / 'nanonav.db'}"
        upgrade(url)
        store = JobStore.from_url(url)
        settings = Settings(database_url=url)
        clock = LockClock(store)
        started = time.perf_counter()
        for seed in range(jobs):
            store.enqueue({**scenario, "seed": seed}, robot_steps=1, episodes=1)
            claim = store.claim("benchmark", lease_s=60)
            assert claim is not None
            run_job(store, claim, settings, threading.Event())
        wall = time.perf_counter() - started
        store.close()
    return clock.held, wall


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="one small job per scenario")
    args = parser.parse_args(argv)
    print(f"{'scenario':22} {'transaction [thread]':52} {'count':>6} {'longest ms':>11}")
    for name, scenario in SCENARIOS.items():
        held, wall = measure(
            {**scenario, **QUICK} if args.quick else scenario, 1 if args.quick else 3
        )
        for kind, times in sorted(held.items(), key=lambda item: -max(item[1])):
            print(f"{name:22} {kind[:52]:52} {len(times):6d} {max(times) * 1e3:11.2f}")
        total = sum(sum(times) for times in held.values())
        print(
            f"{name:22} write lock held {total * 1e3:.1f} ms of {wall:.1f} s: "
            f"{total / wall:.3%} of the time"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
