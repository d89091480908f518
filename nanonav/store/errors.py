"""What the store refuses, as typed exceptions that callers map to their own answers."""

from __future__ import annotations

from nanonav.store.models import JobStatus


class StoreError(Exception):
    """Base of the store's refusals."""


class JobNotFound(StoreError):
    def __init__(self, job_id: int) -> None:
        super().__init__(f"there is no job {job_id}")
        self.job_id = job_id


class StudyNotFound(StoreError):
    def __init__(self, study_id: int) -> None:
        super().__init__(f"there is no study {study_id}")
        self.study_id = study_id


class JobAlreadyFinished(StoreError):
    def __init__(self, job_id: int, status: JobStatus) -> None:
        super().__init__(f"job {job_id} has already finished: it is {status.value}")
        self.job_id = job_id
        self.status = status


class ResultsUnavailable(StoreError):
    def __init__(self, job_id: int, status: JobStatus) -> None:
        if status is JobStatus.CANCELLED:
            message = (
                f"job {job_id} was cancelled before its evaluation: it keeps only its metrics "
                "(the episodes it finished), its Q-table and their pictures, if it started"
            )
        else:
            message = f"job {job_id} is {status.value}; results exist only for succeeded jobs"
        super().__init__(message)
        self.job_id = job_id
        self.status = status


class LeaseLost(StoreError):
    """The worker's claim on a job is no longer valid: the write it tried was not made."""

    def __init__(self, job_id: int) -> None:
        super().__init__(f"the lease on job {job_id} was lost")
        self.job_id = job_id


class QuotaExceeded(StoreError):
    """A submit would take its key past a quota: ``name`` is ``active_jobs`` (queued and
    running jobs) or ``robot_steps`` (their robot-steps)."""

    def __init__(self, name: str, limit: int, used: int, asked: int) -> None:
        what = (
            "queued and running jobs" if name == "active_jobs" else "robot-steps queued and running"
        )
        super().__init__(
            f"the {name} quota allows {limit:,} {what}; {used:,} are in use and this submit "
            f"adds {asked:,}: wait for some to finish, or cancel some"
        )
        self.name = name
        self.limit = limit


class JobNotFinished(StoreError):
    """Only a finished job may be deleted: a worker may still write a queued or running one."""

    def __init__(self, job_id: int, status: JobStatus) -> None:
        super().__init__(
            f"job {job_id} is {status.value}: cancel it first, and delete it once it has ended"
        )
        self.job_id = job_id
        self.status = status


class JobInStudy(StoreError):
    """A study's job goes with its study, so that the study's report never loses a job."""

    def __init__(self, job_id: int, study_id: int) -> None:
        super().__init__(
            f"job {job_id} belongs to study {study_id}: delete the study instead "
            f"(DELETE /studies/{study_id}), which deletes its jobs"
        )
        self.job_id = job_id
        self.study_id = study_id


class StudyNotFinished(StoreError):
    """Only an ended study may be deleted: workers may still write its jobs."""

    def __init__(self, study_id: int, unfinished: int) -> None:
        super().__init__(
            f"study {study_id} has {unfinished} job(s) queued or running: cancel it first, and "
            "delete it once every job has ended"
        )
        self.study_id = study_id
        self.unfinished = unfinished


class IdempotencyKeyReused(StoreError):
    """A key that still holds was sent again with a different request."""

    def __init__(self, key: str, kind: str, made_id: int) -> None:
        super().__init__(
            f"the Idempotency-Key {key!r} was already used, within its lifetime, for a different "
            f"request (it made {kind} {made_id}); send that request again or use a new key"
        )
        self.key = key


class PolicyInUse(StoreError):
    """A policy that queued or running jobs evaluate cannot be deleted under them."""

    def __init__(self, policy_id: int, job_ids: list[int], count: int) -> None:
        shown = ", ".join(map(str, job_ids)) + (", ..." if count > len(job_ids) else "")
        super().__init__(
            f"policy {policy_id} is evaluated by {count} queued or running job(s) ({shown}): "
            "cancel them, or wait for them to finish, then delete it"
        )
        self.policy_id = policy_id
        self.job_ids = job_ids


class PolicyLimitReached(StoreError):
    """A key already keeps as many policies as it may."""

    def __init__(self, limit: int) -> None:
        super().__init__(
            f"this key already keeps {limit:,} policies, the most it may (the quota_policies "
            "setting): delete one it no longer needs, then send this one again"
        )
        self.limit = limit
