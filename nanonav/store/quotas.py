"""How much one key (or, without keys, one client address) may have waiting and running.

The count is taken in the transaction that inserts the new jobs, after a lock that serialises
submits of the same key (SQLite's write lock; on PostgreSQL a transaction-scoped advisory lock
on the key), so concurrent submits cannot together pass a quota that each alone respects.
"""

from __future__ import annotations

from dataclasses import dataclass

from sqlalchemy import func, select
from sqlalchemy.orm import Session

from nanonav.store.db import serialise
from nanonav.store.errors import QuotaExceeded
from nanonav.store.models import Job, JobStatus


@dataclass(frozen=True)
class Quota:
    """The limits of one ``key``; 0 means no limit."""

    key: str
    active_jobs: int
    robot_steps: int

    @property
    def unlimited(self) -> bool:
        return self.active_jobs == 0 and self.robot_steps == 0


def check_quota(session: Session, quota: Quota | None, *, jobs: int, robot_steps: int) -> None:
    """Refuse adding ``jobs`` jobs costing ``robot_steps`` when the key would pass a limit."""
    if quota is None or quota.unlimited:
        return
    serialise(session, quota.key)
    active = select(func.count(), func.coalesce(func.sum(Job.robot_steps), 0)).where(
        Job.quota_key == quota.key, Job.status.in_([JobStatus.QUEUED, JobStatus.RUNNING])
    )
    count, steps = session.execute(active).one()
    if quota.active_jobs and int(count) + jobs > quota.active_jobs:
        raise QuotaExceeded("active_jobs", quota.active_jobs, int(count), jobs)
    if quota.robot_steps and int(steps) + robot_steps > quota.robot_steps:
        raise QuotaExceeded("robot_steps", quota.robot_steps, int(steps), robot_steps)
