"""A running study's report, computed at most once per change and per second, not once per GET.

A study's statistics depend on its jobs' statuses per grid point and on the metrics of its
finished jobs. A finished job never changes again, and the set of finished jobs only grows, so
the jobs per grid point and status (the report's *version*) name the report exactly. Each API
process keeps the last report it computed per study: a GET whose version matches reads one small
aggregate instead of every job's metrics. When the version has moved on, one request computes
the new report while the others are answered with the last one, and a study is computed again
at most every ``min_interval_s``: while it runs, its statistics may lag its counts by about that
much, never more. The first report of a study, and the exact one a finished study keeps, are
waited for.
"""

from __future__ import annotations

import threading
import time
from collections import OrderedDict
from collections.abc import Callable, Hashable
from dataclasses import dataclass, field
from typing import Any

Report = dict[str, Any]
# How often one study's report is computed again while its jobs keep changing, seconds.
MIN_INTERVAL_S = 1.0


@dataclass
class _Kept:
    version: Hashable
    report: Report | None
    computed_at: float
    computing: bool = False
    first: threading.Lock = field(default_factory=threading.Lock)


class Reports:
    """The last report of each of ``size`` studies; thread-safe (routes run on a pool)."""

    def __init__(
        self,
        size: int = 64,
        min_interval_s: float = MIN_INTERVAL_S,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.size = size
        self.min_interval_s = min_interval_s
        self.clock = clock
        self._kept: OrderedDict[Hashable, _Kept] = OrderedDict()
        self._lock = threading.Lock()
        self.computed = 0  # how many were computed, for tests and benchmarks

    def get(
        self,
        study: Hashable,
        version: Hashable,
        compute: Callable[[], Report],
        *,
        exact: bool = False,
    ) -> Report:
        """The report of ``study`` at ``version``, or (unless ``exact``) the last one while a
        newer one is being computed or was computed less than ``min_interval_s`` ago."""
        with self._lock:
            kept = self._kept.get(study)
            if kept is not None:
                self._kept.move_to_end(study)
                if kept.report is not None and kept.version == version:
                    return kept.report
                recent = self.clock() - kept.computed_at < self.min_interval_s
                if kept.report is not None and not exact and (kept.computing or recent):
                    return kept.report
            if kept is None or kept.report is None:
                kept = self._kept.setdefault(study, _Kept(version, None, self.clock()))
                first = kept.first
            else:
                first = None
            kept.computing = True
        if first is not None:
            with first:  # the first report: everyone waits for the one computation
                with self._lock:
                    if kept.report is not None and (kept.version == version or not exact):
                        return kept.report
                return self._compute(study, version, compute)
        return self._compute(study, version, compute)

    def _compute(self, study: Hashable, version: Hashable, compute: Callable[[], Report]) -> Report:
        try:
            report = compute()
        except BaseException:
            with self._lock:
                kept = self._kept.get(study)
                if kept is not None:
                    kept.computing = False
            raise
        with self._lock:
            self.computed += 1
            kept = self._kept.setdefault(study, _Kept(version, report, self.clock()))
            kept.version, kept.report, kept.computed_at = version, report, self.clock()
            kept.computing = False
            self._kept.move_to_end(study)
            while len(self._kept) > self.size:
                self._kept.popitem(last=False)
        return report
