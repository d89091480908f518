"""The job store shared by the API and the worker: models, sessions and every queue query."""

from nanonav.store.errors import (
    JobAlreadyFinished,
    JobNotFound,
    LeaseLost,
    ResultsUnavailable,
    StoreError,
)
from nanonav.store.models import JobStatus
from nanonav.store.queue import Claim, JobRecord, JobStore, Outcome, Page

__all__ = [
    "Claim",
    "JobAlreadyFinished",
    "JobNotFound",
    "JobRecord",
    "JobStatus",
    "JobStore",
    "LeaseLost",
    "Outcome",
    "Page",
    "ResultsUnavailable",
    "StoreError",
]
