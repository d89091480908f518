"""The job store shared by the API and the worker: models, sessions and every queue query."""

from nanonav.store.errors import (
    IdempotencyKeyReused,
    JobAlreadyFinished,
    JobNotFound,
    LeaseLost,
    ResultsUnavailable,
    StoreError,
    StudyNotFound,
)
from nanonav.store.idempotency import Idempotency
from nanonav.store.models import JobStatus
from nanonav.store.queue import Census, Claim, JobRecord, JobStore, Outcome, Page
from nanonav.store.studies import (
    StudyJob,
    StudyJobState,
    StudyPage,
    StudyProgress,
    StudyRecord,
    StudyStore,
)

__all__ = [
    "Census",
    "Claim",
    "Idempotency",
    "IdempotencyKeyReused",
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
    "StudyJob",
    "StudyJobState",
    "StudyNotFound",
    "StudyPage",
    "StudyProgress",
    "StudyRecord",
    "StudyStore",
]
