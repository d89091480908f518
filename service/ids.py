"""The ids that paths carry: spelled one way, and checked for their owner on the value the route
receives.

A route takes ``job_id: JobId``, ``study_id: StudyId`` or ``policy_id: PolicyId``. An id is
written in plain decimal digits (``/jobs/1``); text that is no number from 1 is a 422 naming the
parameter, and any other spelling of a number (``+1``, ``01``, `` 1``, ``1.0``) is a 404, as a
job that does not exist, whose detail names the plain path: one resource, one URL. A policy is
also named as ``policy_from`` names it, ``policy-<id>``. Only then, on that integer, does another
key's job, study or policy become a 404, as one that does not exist.
"""

from __future__ import annotations

from typing import Annotated, Any

from fastapi import Depends, Path, Request
from fastapi.concurrency import run_in_threadpool
from fastapi.exceptions import RequestValidationError
from pydantic import Field, TypeAdapter, ValidationError

from nanonav.scenario import MAX_EXACT_INT
from nanonav.store import JobNotFound, JobStore, PolicyNotFound, StudyNotFound, StudyStore
from nanonav.store.policies import POLICY_PREFIX
from service.problems import ProblemError
from service.security import CallerDep

RawJobId = Annotated[int, Path(ge=1, le=MAX_EXACT_INT, description="The job's id.")]
RawStudyId = Annotated[int, Path(ge=1, le=MAX_EXACT_INT, description="The study's id.")]
RawPolicyName = Annotated[
    str,
    Path(
        max_length=len(POLICY_PREFIX) + len(str(MAX_EXACT_INT)),
        description="The policy's id, or its name as policy_from names it, policy-<id>.",
        examples=["3", "policy-3"],
        # documents the plain spellings; any other is answered by the dependency (404 or 422)
        json_schema_extra={"pattern": r"^(policy-)?[1-9][0-9]{0,14}$"},
    ),
]
# What a number in a path may be, read as leniently as FastAPI reads an ``int`` parameter.
_LENIENT_ID: TypeAdapter[int] = TypeAdapter(Annotated[int, Field(ge=1, le=MAX_EXACT_INT)])


class IdNotCanonical(ProblemError):
    """An id spelled otherwise than in plain digits: not found, as an id no resource has."""

    status = 404

    def __init__(self, kind: str, spelled: str, plain_path: str) -> None:
        super().__init__(
            f"there is no {kind} {spelled!r}: an id is written in plain decimal digits, "
            f"as {plain_path}"
        )
        self.slug = f"{kind}-not-found"
        self.title = f"{kind.capitalize()} not found"


def _plain(request: Request, parameter: str, kind: str, value: int, spelled: str) -> None:
    """Refuse ``spelled``, the path's text for ``parameter``, unless it is ``value`` written
    plainly (a policy's ``policy-`` prefix aside)."""
    if spelled.removeprefix(POLICY_PREFIX if kind == "policy" else "") == str(value):
        return
    params: dict[str, Any] = {**request.path_params, parameter: value}
    plain_path = request.scope["route"].path_format.format(**params)
    raise IdNotCanonical(kind, spelled, plain_path)


async def _owned_job(job_id: RawJobId, request: Request, caller: CallerDep) -> int:
    _plain(request, "job_id", "job", job_id, request.path_params["job_id"])
    # Without keys every job is everyone's, and no thread-pool hop is taken.
    if caller.scoped:
        store: JobStore = request.app.state.store
        if await run_in_threadpool(store.owner_of, job_id) not in {None, caller.owner}:
            raise JobNotFound(job_id)
    return job_id


async def _owned_study(study_id: RawStudyId, request: Request, caller: CallerDep) -> int:
    _plain(request, "study_id", "study", study_id, request.path_params["study_id"])
    if caller.scoped:
        studies: StudyStore = request.app.state.studies
        if await run_in_threadpool(studies.owner_of, study_id) not in {None, caller.owner}:
            raise StudyNotFound(study_id)
    return study_id


def policy_id_of(spelled: str) -> int:
    """The id a policy path parameter names (``3`` or ``policy-3``, in any spelling FastAPI
    reads as that number); a 422 naming ``policy_id`` for text that names none."""
    try:
        return _LENIENT_ID.validate_python(spelled.removeprefix(POLICY_PREFIX))
    except ValidationError:
        detail = (
            f"must be a policy's id, an integer from 1, or its name, policy-<id>; not {spelled!r}"
        )
        error = {"type": "policy_id", "loc": ("path", "policy_id"), "msg": detail}
        raise RequestValidationError([{**error, "input": spelled}]) from None


async def _owned_policy(policy_id: RawPolicyName, request: Request, caller: CallerDep) -> int:
    number = policy_id_of(policy_id)
    _plain(request, "policy_id", "policy", number, policy_id)
    if caller.scoped:
        store: JobStore = request.app.state.store
        owner = await run_in_threadpool(store.policies.owner_of, number)
        if owner not in {None, caller.owner}:
            raise PolicyNotFound(number)
    return number


JobId = Annotated[int, Depends(_owned_job)]
StudyId = Annotated[int, Depends(_owned_study)]
PolicyId = Annotated[int, Depends(_owned_policy)]
