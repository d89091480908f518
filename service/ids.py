"""The ids that paths carry, checked for their owner on the very value the route receives.

A route takes ``job_id: JobId``, ``study_id: StudyId`` or ``policy_id: PolicyId``: the path
parameter is validated as an integer first (``+1``, ``01``, `` 1`` and ``1.0`` all become 1), and
only then, on that integer, does another key's job, study or policy become a 404, as one that
does not exist. A check on the raw text of the path would miss every spelling but the plain one.
"""

from __future__ import annotations

from typing import Annotated

from fastapi import Depends, Path, Request
from fastapi.concurrency import run_in_threadpool

from nanonav.scenario import MAX_EXACT_INT
from nanonav.store import JobNotFound, JobStore, PolicyNotFound, StudyNotFound, StudyStore
from service.security import CallerDep

RawJobId = Annotated[int, Path(ge=1, le=MAX_EXACT_INT, description="The job's id.")]
RawStudyId = Annotated[int, Path(ge=1, le=MAX_EXACT_INT, description="The study's id.")]
RawPolicyId = Annotated[int, Path(ge=1, le=MAX_EXACT_INT, description="The policy's id.")]


async def _owned_job(job_id: RawJobId, request: Request, caller: CallerDep) -> int:
    # Without keys every job is everyone's, and no thread-pool hop is taken.
    if caller.scoped:
        store: JobStore = request.app.state.store
        if await run_in_threadpool(store.owner_of, job_id) not in {None, caller.owner}:
            raise JobNotFound(job_id)
    return job_id


async def _owned_study(study_id: RawStudyId, request: Request, caller: CallerDep) -> int:
    if caller.scoped:
        studies: StudyStore = request.app.state.studies
        if await run_in_threadpool(studies.owner_of, study_id) not in {None, caller.owner}:
            raise StudyNotFound(study_id)
    return study_id


async def _owned_policy(policy_id: RawPolicyId, request: Request, caller: CallerDep) -> int:
    if caller.scoped:
        store: JobStore = request.app.state.store
        owner = await run_in_threadpool(store.policies.owner_of, policy_id)
        if owner not in {None, caller.owner}:
            raise PolicyNotFound(policy_id)
    return policy_id


JobId = Annotated[int, Depends(_owned_job)]
StudyId = Annotated[int, Depends(_owned_study)]
PolicyId = Annotated[int, Depends(_owned_policy)]
