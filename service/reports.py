"""A running study's report, computed once per change rather than once per GET.

A study's statistics depend on its jobs' statuses per grid point and on the metrics of its
finished jobs. A finished job never changes again, and the set of finished jobs only grows, so
the jobs per grid point and status name the report exactly: each API process keeps the last
reports it computed under that key, and a client polling a 2,000-job study reads one small
aggregate instead of every job's metrics. Clients that miss at once wait for one computation.
"""

from __future__ import annotations

import threading
from collections import OrderedDict
from collections.abc import Callable, Hashable
from typing import Any

Report = dict[str, Any]


class Reports:
    """The ``size`` reports last computed, by key; thread-safe (routes run on a pool)."""

    def __init__(self, size: int = 64) -> None:
        self.size = size
        self._found: OrderedDict[Hashable, Report] = OrderedDict()
        self._computing: dict[Hashable, threading.Lock] = {}
        self._lock = threading.Lock()
        self.computed = 0  # how many were computed, for tests and benchmarks

    def get(self, key: Hashable, compute: Callable[[], Report]) -> Report:
        """The report kept under ``key``, else what ``compute`` gives, kept."""
        with self._lock:
            if key in self._found:
                self._found.move_to_end(key)
                return self._found[key]
            computing = self._computing.setdefault(key, threading.Lock())
        with computing:
            with self._lock:
                if key in self._found:
                    return self._found[key]
            try:
                report = compute()
            finally:
                with self._lock:
                    self._computing.pop(key, None)
            with self._lock:
                self.computed += 1
                self._found[key] = report
                while len(self._found) > self.size:
                    self._found.popitem(last=False)
            return report
