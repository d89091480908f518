"""Where a job or a study is in its life: the one vocabulary of the store, the API's schemas,
the studies' reports and the client. Plain data, imported by the light client too; the store's
``JobStatus`` enum holds the same values (a test pins them)."""

from __future__ import annotations

from typing import Literal, get_args

Status = Literal["queued", "running", "succeeded", "failed", "cancelled"]
"""queued (waiting for a worker), running, then one of the three that never change again."""
STATUSES: tuple[Status, ...] = get_args(Status)
FINISHED: frozenset[Status] = frozenset({"succeeded", "failed", "cancelled"})
"""The statuses that never change again."""
