"""Server-Sent Events: a job's or a study's state, sent as it changes, until it has finished.

Every event carries the whole current state (a job as `GET /jobs/{id}` answers it, a study as
:class:`StudyState`): ``event: status`` when the status differs from the one the client last
had, ``event: progress`` otherwise. Its ``id`` is ``<status>-<digest of the data>``, so a client
that reconnects with ``Last-Event-ID`` is not sent the state it already has; one that already
has a finished state gets ``204 No Content``, which tells ``EventSource`` to stop reconnecting.
Unknown ids get 404 before the stream starts, and a caller past its streams, or a server past
its own (``StreamLimits``), gets 503 with ``Retry-After``. Between events FastAPI sends a
``: ping`` comment every 15 s (``fastapi.sse._PING_INTERVAL``; FastAPI offers no setting for
it), which keeps idle streams open through proxies.
"""

from __future__ import annotations

from collections.abc import AsyncIterable, AsyncIterator, Collection, Mapping
from dataclasses import dataclass
from typing import Annotated, Any

from fastapi import APIRouter, Depends, Header, Request
from fastapi.responses import Response
from fastapi.sse import EventSourceResponse, ServerSentEvent

from nanonav.status import FINISHED
from nanonav.store import JobRecord, JobStore, StudyNotFound, StudyProgress, StudyStore
from nanonav.studies.report import status_of
from service.deps import JobEventsDep, StoreDep, StudiesDep, StudyEventsDep
from service.events import Channel, Snapshot, StreamLimits
from service.ids import JobId, StudyId
from service.problems import PROBLEM_JSON, EventsUnavailable
from service.schemas import Job, JobCounts, StudyState
from service.security import caller_of

router = APIRouter(tags=["events"])

# Browsers reconnect this long after a stream drops (the SSE default is left to each browser).
RETRY_MS = 1000
LastEventId = Annotated[
    str | None,
    Header(max_length=200, description="The id of the last event received, to resume from."),
]
# Problems spelled out: `problems()` would also list them under the stream's media type.
_PROBLEM = {PROBLEM_JSON: {"schema": {"$ref": "#/components/schemas/Problem"}}}
STREAM: dict[int | str, dict[str, Any]] = {
    200: {"description": "A text/event-stream: `status` and `progress` events."},
    204: {"description": "The client already has the final state (Last-Event-ID): nothing new."},
    **{status: {"description": "A problem", "content": _PROBLEM} for status in (404, 422, 503)},
}


class NothingNew(Exception):
    """The client already has the final state: answered with 204 No Content."""


async def nothing_new(request: Request, exc: Exception) -> Response:
    return Response(status_code=204)


@dataclass(frozen=True)
class Start:
    """Where a stream starts: the state now, and what the client already has of it."""

    thing_id: int
    current: Snapshot
    seen_status: str | None  # the status of the state the client had, if it said
    send_current: bool


def job_snapshot(job: JobRecord) -> Snapshot:
    data = Job.of(job).model_dump_json(by_alias=True)
    return Snapshot.of(job.status.value, data, finished=job.status.finished)


def job_snapshots(store: JobStore, job_ids: Collection[int]) -> Mapping[int, Snapshot]:
    """Every watched job's state, from one query."""
    return {job_id: job_snapshot(job) for job_id, job in store.get_many(job_ids).items()}


def study_snapshot(progress: StudyProgress) -> Snapshot:
    found = {status.value: n for status, n in progress.jobs.items()}
    jobs = JobCounts.of(found)
    status = status_of(found, progress.cancel_requested)
    state = StudyState(
        id=progress.study_id,
        status=status,
        jobs=jobs,
        progress=min(progress.work_done / max(jobs.total, 1), 1.0),
        finished_at=progress.last_finished_at if status in FINISHED else None,
    )
    return Snapshot.of(status, state.model_dump_json(), finished=status in FINISHED)


def study_snapshots(studies: StudyStore, study_ids: Collection[int]) -> Mapping[int, Snapshot]:
    """Every watched study's state, from one query."""
    return {i: study_snapshot(progress) for i, progress in studies.progress(study_ids).items()}


def _start(thing_id: int, current: Snapshot, last_event_id: str | None) -> Start:
    if last_event_id == current.event_id:
        if current.finished:
            raise NothingNew
        return Start(thing_id, current, current.status, send_current=False)
    seen_status = None if last_event_id is None else last_event_id.partition("-")[0]
    return Start(thing_id, current, seen_status, send_current=True)


def _job_start(
    job_id: JobId, store: StoreDep, channel: JobEventsDep, last_event_id: LastEventId = None
) -> Start:
    """Read before the stream starts, so that an unknown job is a 404, not an empty stream."""
    _check(channel)
    return _start(job_id, job_snapshot(store.get(job_id)), last_event_id)


def _study_start(
    study_id: StudyId,
    studies: StudiesDep,
    channel: StudyEventsDep,
    last_event_id: LastEventId = None,
) -> Start:
    """Read before the stream starts, so that an unknown study is a 404."""
    _check(channel)
    found = studies.progress([study_id])
    if study_id not in found:
        raise StudyNotFound(study_id)
    return _start(study_id, study_snapshot(found[study_id]), last_event_id)


async def _place(request: Request) -> AsyncIterator[None]:
    """A place among the open streams, taken before anything is read and held until the
    stream ends (FastAPI closes a request's dependencies after its response)."""
    streams: StreamLimits = request.app.state.streams
    with streams.hold(caller_of(request).quota_key):
        yield


Place = Annotated[None, Depends(_place)]


def _check(channel: Channel) -> None:
    if not channel.running:
        raise EventsUnavailable(
            "this server is not following changes now; poll GET /jobs/{id} or try again"
        )


@router.get("/jobs/{job_id}/events", response_class=EventSourceResponse, responses=STREAM)
async def job_events(
    place: Place, start: Annotated[Start, Depends(_job_start)], channel: JobEventsDep
) -> AsyncIterable[ServerSentEvent]:
    """The job's state now, then each change (`progress` while queued or running, `status`
    when its status changes), ending after the event that shows it finished."""
    async for event in _stream(channel, start):
        yield event


@router.get("/studies/{study_id}/events", response_class=EventSourceResponse, responses=STREAM)
async def study_events(
    place: Place, start: Annotated[Start, Depends(_study_start)], channel: StudyEventsDep
) -> AsyncIterable[ServerSentEvent]:
    """The study's jobs per status and progress now, then each change, ending once it has
    finished."""
    async for event in _stream(channel, start):
        yield event


async def _stream(channel: Channel, start: Start) -> AsyncIterable[ServerSentEvent]:
    current, seen = start.current, start.seen_status
    if start.send_current:
        yield _event(current, seen, retry=RETRY_MS)
        seen = current.status
    else:
        yield ServerSentEvent(retry=RETRY_MS)
    if current.finished:
        return
    with channel.listen(start.thing_id, current.event_id) as listener:
        while not current.finished:
            found = await listener.next()
            if found is None:  # the server is stopping (a client that reconnects resumes)
                # or the job or study was deleted (one that reconnects gets 404)
                return
            yield _event(found, seen)
            current, seen = found, found.status


def _event(
    snapshot: Snapshot, seen_status: str | None, retry: int | None = None
) -> ServerSentEvent:
    kind = "progress" if snapshot.status == seen_status else "status"
    return ServerSentEvent(raw_data=snapshot.data, event=kind, id=snapshot.event_id, retry=retry)
