"""The job store shared by the API and the worker: models, sessions and every queue query."""

from nanonav.store.errors import (
    IdempotencyKeyReused,
    JobAlreadyFinished,
    JobInStudy,
    JobNotFinished,
    JobNotFound,
    LeaseLost,
    ResultsUnavailable,
    StoreError,
    StudyNotFinished,
    StudyNotFound,
)
from nanonav.store.idempotency import Idempotency
from nanonav.store.models import JobStatus
from nanonav.store.policies import (
    PolicyNotFound,
    PolicyPage,
    PolicyRecord,
    PolicySource,
    PolicyStore,
    policy_name,
    policy_number,
)
from nanonav.store.queue import Census, Claim, JobRecord, JobStore, Outcome, Page
from nanonav.store.retention import Expired, RetentionStore
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
    "Expired",
    "Idempotency",
    "IdempotencyKeyReused",
    "JobAlreadyFinished",
    "JobInStudy",
    "JobNotFinished",
    "JobNotFound",
    "JobRecord",
    "JobStatus",
    "JobStore",
    "LeaseLost",
    "Outcome",
    "Page",
    "PolicyNotFound",
    "PolicyPage",
    "PolicyRecord",
    "PolicySource",
    "PolicyStore",
    "ResultsUnavailable",
    "RetentionStore",
    "StoreError",
    "StudyJob",
    "StudyJobState",
    "StudyNotFinished",
    "StudyNotFound",
    "StudyPage",
    "StudyProgress",
    "StudyRecord",
    "StudyStore",
    "policy_name",
    "policy_number",
]
