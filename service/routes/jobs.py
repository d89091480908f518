"""Jobs: submit, watch, list, cancel, delete, and fetch results as JSON, arrays or pictures."""

from __future__ import annotations

import csv
import io
import secrets
from collections.abc import Iterator
from functools import partial
from typing import Annotated, Any, Literal

import numpy as np
from fastapi import APIRouter, Body, Query, Response
from fastapi.concurrency import run_in_threadpool
from fastapi.responses import StreamingResponse
from numpy.typing import NDArray

from nanonav.engine import SimulationResult
from nanonav.extxyz import xyz_frames
from nanonav.pictures import job as pictures
from nanonav.policy import greedy_table
from nanonav.scenario import MAX_EXACT_INT, Policy, Scenario
from nanonav.store import JobStatus, JobStore, ResultsUnavailable, StudyNotFound
from nanonav.store.arrays import pack
from service.budget import check_budget, check_quota_fits
from service.caching import IMMUTABLE
from service.callbacks import CallbackUrl, callback_answer, check_callback
from service.deps import DeliveriesDep, DrawerDep, JsonBody, SettingsDep, StoreDep, StudiesDep
from service.drawing import Drawer, kept_name
from service.idempotency import IdempotencyDep
from service.ids import JobId
from service.paging import Cursor, decode_cursor, encode_cursor
from service.policy_from import check_policy_from, policies_kept
from service.problems import (
    InvalidInput,
    NoCallback,
    NoQTable,
    NoTreatment,
    field_error,
    problems,
)
from service.responses import FiniteJSONResponse
from service.schemas import (
    Callback,
    GreedyState,
    Job,
    JobPage,
    Metrics,
    QTable,
    Trajectory,
    offers_qtable,
)
from service.security import SCRIPTED_ONLY, CallerDep, owned_tables, quota_of
from service.waiting import waiting_for

router = APIRouter(prefix="/jobs", tags=["jobs"])

# Seeds drawn for a submit that names none: any 32-bit integer.
DRAWN_SEEDS = 2**32
# Pictures of what a cancelled job keeps: the episodes it finished and the table it learned.
KEPT_PICTURES = ("learning", "qtable")

PNG: dict[int | str, dict[str, Any]] = {
    200: {"content": {"image/png": {}}, "description": "A PNG picture."}
}
NOT_FOUND_OR_NOT_READY = problems(404, 409, 422)

SCENARIO_EXAMPLES: dict[str, Any] = {
    "defaults": {"summary": "All defaults", "value": {}},
    "tiny": {
        "summary": "A quick run",
        "value": {"seed": 7, "learning": {"episodes": 2, "max_steps": 100}},
    },
    "swarm": {"summary": "The paper's swarm", "value": {"preset": "paper-swarm"}},
}


@router.post(
    "",
    status_code=202,
    response_model=Job,
    dependencies=[JsonBody],
    responses=problems(400, 403, 413, 415, 422, 429),
)
def submit_job(
    scenario: Annotated[Scenario, Body(openapi_examples=SCENARIO_EXAMPLES)],
    store: StoreDep,
    settings: SettingsDep,
    caller: CallerDep,
    response: Response,
    idempotency: IdempotencyDep,
    callback_url: CallbackUrl = None,
) -> Job:
    """Queue a scenario to run; answers once the job is stored.

    A scenario the schema allows may still be refused with 422, each error typed by its rule:
    ``scenario_rule`` (fields that must agree, as the scenario's description says),
    ``budget_exceeded`` (more work than the server's budget), ``policy_unusable`` (a
    ``policy_from`` naming no table this scenario can evaluate), ``refused`` (a
    ``callback_url`` the server will not call), ``idempotency_key`` (a blank, non-UTF-8 or
    over-long key), ``idempotency_key_reused`` (a key already used for another request) and
    ``nul_character`` (U+0000 in any string of the body, key or value, in ``callback_url`` or
    in the key: the store cannot keep it)."""
    check_callback(callback_url, settings)
    if "seed" not in scenario.model_fields_set:
        # each submit without a seed is a new sample; the seed drawn is stored, to repeat it
        scenario = scenario.model_copy(update={"seed": secrets.randbelow(DRAWN_SEEDS)})
    multiply_adds = check_policy_from(
        scenario, owned_tables(store, caller), ("body", "policy_from"), settings=settings
    )
    check_budget(scenario, settings, multiply_adds=multiply_adds)
    quota = quota_of(caller, settings)
    check_quota_fits(quota, jobs=1, robot_steps=scenario.robot_steps_budget, blame=[["body"]])
    with policies_kept(lambda _: (("body", "policy_from"), "")):
        job = store.enqueue(
            scenario.model_dump(mode="json"),
            robot_steps=scenario.robot_steps_budget,
            episodes=scenario.episodes,
            idempotency=idempotency,
            callback_url=callback_url,
            owner=caller.owner,
            quota=quota,
        )
    response.headers["Location"] = f"/jobs/{job.id}"
    return Job.of(job, waiting_for=waiting_for(job, store))


@router.get("", response_model=JobPage, responses=problems(404, 422))
def list_jobs(
    store: StoreDep,
    studies: StudiesDep,
    caller: CallerDep,
    status: Annotated[JobStatus | None, Query(description="Only jobs in this state.")] = None,
    study: Annotated[
        int | None, Query(ge=1, le=MAX_EXACT_INT, description="Only the jobs of this study.")
    ] = None,
    policy: Annotated[Policy | None, Query(description="Only jobs of this policy.")] = None,
    limit: Annotated[int, Query(ge=1, le=100, description="Jobs per page.")] = 20,
    cursor: Cursor = None,
) -> JobPage:
    """A page of jobs, newest first; with API keys, only the caller's own. A ``study`` that is
    not there (or is another key's) is a 404."""
    if study is not None:
        owner = studies.owner_of(study)
        if owner is None or (caller.scoped and owner != caller.owner):
            raise StudyNotFound(study)
    before = None if cursor is None else decode_cursor(cursor)
    page = store.page(
        status=status,
        limit=limit,
        before_id=before,
        study_id=study,
        policy=policy,
        owner=caller.only,
    )
    next_cursor = None if page.next_before_id is None else encode_cursor(page.next_before_id)
    next_url = None
    if next_cursor is not None:
        query = f"limit={limit}&cursor={next_cursor}"
        if study is not None:
            query = f"study={study}&{query}"
        if policy is not None:
            query = f"policy={policy}&{query}"
        if status is not None:
            query = f"status={status.value}&{query}"
        next_url = f"/jobs?{query}"
    return JobPage(jobs=[Job.of(j) for j in page.jobs], next_cursor=next_cursor, next=next_url)


@router.get("/{job_id}", response_model=Job, responses=problems(404, 422))
async def get_job(job_id: JobId, store: StoreDep) -> Job:
    """A job's state and progress."""
    # What clients poll most: only the read goes to the thread pool (a plain ``def`` route
    # would also send the answer's validation there, a second hop per request).
    job = await run_in_threadpool(store.get, job_id)
    if job.trains and job.status is JobStatus.QUEUED:
        return Job.of(job, waiting_for=await run_in_threadpool(waiting_for, job, store))
    return Job.of(job)


@router.post(
    "/{job_id}/cancel",
    response_model=Job,
    responses=problems(403, 404, 409, 415, 422),
    openapi_extra=SCRIPTED_ONLY,
)
def cancel_job(job_id: JobId, store: StoreDep) -> Job:
    """Cancel a job: a queued one at once, a running one within about a second.

    200 when the job is or will be cancelled (asking twice is harmless); 409 when it already
    ended another way, succeeded or failed."""
    return Job.of(store.cancel(job_id))


@router.delete(
    "/{job_id}",
    status_code=204,
    response_class=Response,
    responses={204: {"description": "Deleted."}, **problems(403, 404, 409, 415, 422)},
    openapi_extra=SCRIPTED_ONLY,
)
def delete_job(job_id: JobId, store: StoreDep) -> Response:
    """Delete a finished job (succeeded, failed or cancelled) with its results and pictures.

    409 for a queued or running job (cancel it first) and for a job of a study (delete the
    study instead); 404 once it is gone. A webhook it has not sent yet is still sent."""
    store.delete(job_id)
    return Response(status_code=204)


@router.get("/{job_id}/callback", response_model=Callback, responses=problems(404, 422))
def get_callback(job_id: JobId, store: StoreDep, deliveries: DeliveriesDep) -> Callback:
    """The webhook the job sends when it ends (its ``callback_url``), and how sending it went."""
    store.get(job_id)
    record = deliveries.for_job(job_id)
    if record is None:
        raise NoCallback(f"job {job_id} was submitted without a callback_url")
    return callback_answer(record)


@router.get("/{job_id}/metrics", response_model=Metrics, responses=NOT_FOUND_OR_NOT_READY)
def get_metrics(job_id: JobId, store: StoreDep, response: Response) -> Metrics:
    """The summary (the paper's Table 1), one row per robot, and the learning curve."""
    metrics = Metrics.model_validate(store.metrics(job_id))
    response.headers.update(IMMUTABLE)  # only a succeeded job has them, and they never change
    return metrics


@router.get(
    "/{job_id}/trajectory",
    response_model=Trajectory,
    responses={
        **NOT_FOUND_OR_NOT_READY,
        200: {
            "content": {"application/octet-stream": {}, "text/csv": {}, "chemical/x-xyz": {}},
            "description": "JSON, or an .npz / .csv / extended .xyz download with ?format=.",
        },
    },
)
def get_trajectory(
    job_id: JobId,
    store: StoreDep,
    settings: SettingsDep,
    stride: Annotated[int, Query(ge=1, le=1_000_000, description="Keep every N-th step.")] = 1,
    format: Annotated[Literal["json", "npz", "csv", "xyz"], Query()] = "json",
) -> Any:
    """The evaluation episode's paths, concentrations and distances, every ``stride`` steps.

    A JSON answer holds at most ``NANONAV_TRAJECTORY_JSON_VALUES`` numbers; a larger one is
    refused with 422 naming the stride that fits. ``npz`` is the stored file itself (at
    stride 1); CSV and ``xyz`` (extended XYZ, a frame per step with the robots, cells and
    obstacles, for OVITO, ParaView, VMD or ASE: ``nanonav.extxyz``) are streamed, so all three
    work at any size."""
    name = f"nanonav-job-{job_id}-trajectory"
    download = {"Content-Disposition": f'attachment; filename="{name}.{format}"', **IMMUTABLE}
    if format == "npz" and stride == 1:
        blob = store.trajectory_npz(job_id) or pack({})
        return Response(blob, media_type="application/octet-stream", headers=download)
    arrays = store.trajectory(job_id)
    rows = _rows(arrays, stride)
    strided = {k: (v[rows] if _per_row(arrays, k) else v) for k, v in arrays.items()}
    if format == "npz":
        return Response(pack(strided), media_type="application/octet-stream", headers=download)
    if format == "csv":
        delivers = pictures.treatment_drawn(store.get(job_id).scenario)
        return StreamingResponse(
            _csv_lines(strided, loads=delivers), media_type="text/csv; charset=utf-8",
            headers=download,
        )  # fmt: skip
    if format == "xyz":
        scenario = Scenario.model_validate(store.get(job_id).scenario)
        frames = xyz_frames(arrays, scenario, rows)
        return StreamingResponse(frames, media_type="chemical/x-xyz", headers=download)
    limit = settings.trajectory_json_values
    values = _json_values(arrays, len(rows))
    if values > limit:
        detail = (
            f"the trajectory at stride {stride} holds {values:,} numbers, over the {limit:,} a "
            f"JSON answer may hold: {_fitting_stride(arrays, limit)}"
        )
        raise InvalidInput(detail, [field_error(["query", "stride"], detail, "too_large")])
    return FiniteJSONResponse(
        Trajectory(
            stride=stride,
            length=int(arrays["step"][-1]),
            step=strided["step"].tolist(),
            robots=strided["robots"].tolist(),
            cells=strided["cells"].tolist(),
            obstacles=strided["obstacles"].tolist(),
            obstacle_radius=float(arrays["obstacle_radius"]),
            concentration=strided["concentration"].tolist(),
            distance=strided["distance"].tolist(),
            reached=arrays["reached"].tolist(),
            robot_steps=arrays["robot_steps"].tolist(),
            headings=strided["headings"].tolist() if "headings" in strided else None,
            sensed=strided["sensed"].tolist() if "sensed" in strided else None,
            cell_loads=strided["cell_loads"].tolist() if "cell_loads" in strided else None,
            delivered_to=arrays["delivered_to"].tolist() if "delivered_to" in arrays else None,
            signals=strided["signals"].tolist() if "signals" in strided else None,
        ).model_dump(),
        headers=IMMUTABLE,
    )


@router.get(
    "/{job_id}/qtable",
    response_model=QTable,
    responses={
        **NOT_FOUND_OR_NOT_READY,
        200: {
            "content": {"application/octet-stream": {}, "text/csv": {}},
            "description": "JSON, or an .npz / .csv download with ?format=.",
        },
    },
)
def get_qtable(
    job_id: JobId,
    store: StoreDep,
    format: Annotated[Literal["json", "npz", "csv"], Query()] = "json",
) -> Any:
    """The learned action values and visit counts, with state and action labels, and the
    greedy action of every state.

    ``npz`` holds the arrays ``states``, ``actions``, ``values`` and ``visits``; ``csv`` has a
    row per state and action. A job that has no table (its robots followed a fixed rule, a
    network decided, or it trained for 0 episodes without a policy_from) is a 404
    ``no-qtable`` saying which, as its links offer none."""
    arrays = _qtable(store, job_id)
    if format != "json":
        name = f"nanonav-job-{job_id}-qtable.{format}"
        download = {"Content-Disposition": f'attachment; filename="{name}"', **IMMUTABLE}
        if format == "npz":
            return Response(pack(arrays), media_type="application/octet-stream", headers=download)
        return StreamingResponse(
            _qtable_csv_lines(arrays), media_type="text/csv; charset=utf-8", headers=download
        )
    states = arrays["states"].tolist()
    actions = arrays["actions"].tolist()
    greedy = greedy_table(states, actions, arrays["values"], arrays["visits"])
    table = QTable(
        states=states,
        actions=actions,
        values=arrays["values"].tolist(),
        visits=arrays["visits"].tolist(),
        greedy=[GreedyState.model_validate(g.to_dict()) for g in greedy],
    )
    return FiniteJSONResponse(table.model_dump(), headers=IMMUTABLE)


@router.get(
    "/{job_id}/heatmap.png",
    response_class=Response,
    responses={**PNG, **problems(404, 409, 422, 503)},
)
async def get_heatmap(
    job_id: JobId,
    store: StoreDep,
    drawer: DrawerDep,
    plane: Annotated[Literal["xy", "xz", "yz", "all"], Query()] = "xy",
    at: Annotated[
        float | None,
        Query(
            allow_inf_nan=False,
            description="Where the slice cuts the plane's normal axis (z for xy), within "
            "[-size/2, size/2] of the job's cube; by default through the cell nearest to robot 0.",
        ),
    ] = None,
    resolution: Annotated[
        int,
        Query(
            ge=pictures.MIN_HEATMAP_RESOLUTION,
            le=pictures.MAX_HEATMAP_RESOLUTION,
            description="Grid pixels per side of each slice (the PNG's size does not change).",
        ),
    ] = pictures.HEATMAP_RESOLUTION,
) -> Response:
    """The biomarker concentration in a plane, with the robots' paths projected on it. The
    default slice is kept once drawn; one chosen with ``at`` or ``resolution`` is drawn anew."""
    name = f"heatmap_{plane}"
    if at is None and resolution == pictures.HEATMAP_RESOLUTION:
        return await _picture(store, drawer, job_id, name)
    await run_in_threadpool(_check_heatmap_request, store, job_id, at)
    key = ("job", job_id, name, at, resolution)
    png = await drawer.draw(key, partial(_draw_heatmap, store, job_id, name, at, resolution))
    return Response(png, media_type="image/png", headers=IMMUTABLE)


def _check_heatmap_request(store: JobStore, job_id: int, at: float | None) -> None:
    """404 for no such job, 422 naming ``at`` when the slice would lie outside the job's cube,
    409 for a job that has not succeeded: before a drawing is queued."""
    job = store.get(job_id)
    half = Scenario.model_validate(job.scenario).space.size / 2
    if at is not None and not -half <= at <= half:
        detail = f"at must be within [{-half:g}, {half:g}], the job's cube; it is {at:g}"
        raise InvalidInput(detail, [field_error(["query", "at"], detail, "out_of_range")])
    if job.status is not JobStatus.SUCCEEDED:
        raise ResultsUnavailable(job_id, job.status)


def _draw_heatmap(
    store: JobStore, job_id: int, name: str, at: float | None, resolution: int
) -> bytes:
    """A heatmap at a chosen slice or resolution: drawn for this request, not stored."""
    result = SimulationResult.from_stored(store.metrics(job_id), store.trajectory(job_id))
    return pictures.render(result, name, at=at, resolution=resolution)


@router.get(
    "/{job_id}/plots/{name}.png",
    response_class=Response,
    responses={**PNG, **problems(404, 409, 422, 503)},
)
async def get_plot(
    job_id: JobId,
    name: Literal["trajectory", "concentration", "learning", "qtable", "treatment"],
    store: StoreDep,
    drawer: DrawerDep,
) -> Response:
    """A picture of the run: 3-D trajectory, concentration over time, learning curve, the
    learned Q-table (404 for a job that has none, as ``GET /jobs/{id}/qtable``), or the
    swarm's treatment over time (404 for a job whose robots neither take up space, treat cells
    nor signal).

    The job's links name a picture with ``?v=`` the version of its drawing once it has been
    drawn anew, so that no cache keeps an older one; any ``v`` gets the current drawing."""
    return await _picture(store, drawer, job_id, name)


async def _picture(store: JobStore, drawer: Drawer, job_id: int, name: str) -> Response:
    """The stored picture, or drawn now (off the event loop) and stored for next time, under
    the version of its drawing: a copy of an older drawing is drawn again."""
    if name == "treatment":
        await run_in_threadpool(_check_treatment, store, job_id)
    stored_as = kept_name(name, pictures.version(name))
    kept = name in KEPT_PICTURES
    png = await run_in_threadpool(partial(store.plot, job_id, stored_as, kept=kept))
    if png is None:
        draw = partial(_draw, store, job_id, name, stored_as)
        png = await drawer.draw(("job", job_id, stored_as), draw)
    return Response(png, media_type="image/png", headers=IMMUTABLE)


def _draw(store: JobStore, job_id: int, name: str, stored_as: str) -> bytes:
    """Draw ``name`` from what it shows: the Q-table's arrays, or the metrics and trajectory
    (the learning curve reads only the metrics, as a cancelled job keeps no trajectory)."""
    if name == "qtable":
        png = _qtable_png(store, job_id)
    else:
        metrics = store.metrics(job_id)
        arrays = {} if name == "learning" else store.trajectory(job_id)
        png = pictures.render(SimulationResult.from_stored(metrics, arrays), name)
    store.save_plot(job_id, stored_as, png)
    return png


def _check_treatment(store: JobStore, job_id: int) -> None:
    """404 for a job whose robots deliver no payload, before a drawing is queued."""
    scenario = store.get(job_id).scenario
    if not pictures.treatment_drawn(scenario):
        raise NoTreatment(
            f"job {job_id} has no treatment to draw: its robots deliver no payload, as its cells "
            "cannot be treated (cells.capacity is null) and its robots do not signal "
            "(communication.model is 'none')"
        )


def _qtable(store: JobStore, job_id: int) -> dict[str, NDArray[Any]]:
    """The job's Q-table, if it offers one (``schemas.offers_qtable``): 404 ``no-qtable``
    saying why it has none; 409 while it has no results."""
    arrays = store.qtable(job_id)
    job = store.get(job_id)
    if arrays and offers_qtable(job):
        return arrays
    scenario = job.scenario
    source = scenario.get("policy_from")
    policy = (scenario.get("robots") or {}).get("policy", "q_learning")
    if policy != "q_learning":
        why = f"its robots used the {policy!r} policy, and only q_learning learns one"
    elif isinstance(source, str) and not arrays:
        why = f"it evaluated {source}, a network, which has none"
    elif not arrays:
        why = "it kept none"
    else:
        why = (
            "it trained for 0 episodes (learning.episodes) and evaluated no policy_from, so its "
            "table holds nothing learned"
        )
    raise NoQTable(f"job {job_id} learned no Q-table: {why}")


def _qtable_png(store: JobStore, job_id: int) -> bytes:
    arrays = _qtable(store, job_id)
    return pictures.qtable_png(
        arrays["states"].tolist(), arrays["actions"].tolist(), arrays["values"], arrays["visits"]
    )


PER_ROW = ("step", "robots", "cells", "obstacles", "concentration", "distance", "headings",
           "sensed", "cell_loads", "signals")  # fmt: skip


def _per_row(arrays: dict[str, NDArray[Any]], key: str) -> bool:
    """Whether ``key`` has a row per recorded step (obstacles that never move have one row)."""
    return key in arrays and key in PER_ROW and arrays[key].shape[0] == arrays["step"].shape[0]


def _json_values(arrays: dict[str, NDArray[Any]], rows: int) -> int:
    """How many numbers a JSON answer with ``rows`` rows holds."""
    per_row = sum(int(arrays[k][0].size) for k in PER_ROW if _per_row(arrays, k))
    once = [k for k in PER_ROW if k in arrays and not _per_row(arrays, k)]
    per_robot = [k for k in ("reached", "robot_steps", "delivered_to") if k in arrays]
    fixed = sum(int(arrays[k].size) for k in (*once, *per_robot))
    return rows * per_row + fixed


def _fitting_stride(arrays: dict[str, NDArray[Any]], limit: int) -> str:
    total = int(arrays["step"].shape[0])
    for stride in (2, 5, 10, 20, 50, 100, 200, 500, 1000, 10_000, 100_000):
        if stride < total and _json_values(arrays, -(-total // stride) + 1) <= limit:
            return f"ask for ?stride={stride} or more, or for ?format=npz"
    return "ask for ?format=npz (or ?format=csv)"


def _rows(arrays: dict[str, NDArray[Any]], stride: int) -> NDArray[np.int64]:
    last = int(arrays["robots"].shape[0] - 1)
    rows = np.arange(0, last + 1, stride, dtype=np.int64)
    if rows[-1] != last:
        rows = np.append(rows, last)
    return rows


def _csv_lines(arrays: dict[str, NDArray[Any]], *, loads: bool) -> Iterator[str]:
    """The trajectory as CSV, a recorded step at a time, so a large one is never held whole;
    ``loads``: the cells' payloads as a column, for a swarm that delivers them (every run
    records them, but elsewhere they are all 0 and mean nothing)."""
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    # the active Brownian physics adds each robot's heading and its (noisy) sensed reading
    swimming = "headings" in arrays and "sensed" in arrays
    extra = ["heading_x", "heading_y", "heading_z", "sensed"] if swimming else []
    # the swarm: each cell's payloads so far, and each robot's net signal with communication
    loads = loads and "cell_loads" in arrays
    signals = "signals" in arrays
    extra += ["load"] if loads else []
    extra += ["signal"] if signals else []
    blank = [""] * len(extra)
    writer.writerow(["step", "kind", "index", "x", "y", "z", "concentration", "distance", *extra])
    obstacles_move = _per_row(arrays, "obstacles")
    for i, step in enumerate(arrays["step"].tolist()):
        for r, (x, y, z) in enumerate(arrays["robots"][i].tolist()):
            c = arrays["concentration"][i, r]
            d = arrays["distance"][i, r]
            more = []
            if swimming:
                more = [repr(float(v)) for v in (*arrays["headings"][i, r], arrays["sensed"][i, r])]
            more += [""] if loads else []
            more += [repr(float(arrays["signals"][i, r]))] if signals else []
            writer.writerow([step, "robot", r, x, y, z, repr(float(c)), repr(float(d)), *more])
        for k, (x, y, z) in enumerate(arrays["cells"][i].tolist()):
            load = [""] * (4 if swimming else 0) + (
                [int(arrays["cell_loads"][i, k])] if loads else []
            )
            load += [""] if signals else []
            writer.writerow([step, "cell", k, x, y, z, "", "", *load])
        if obstacles_move or i == 0:
            for k, (x, y, z) in enumerate(arrays["obstacles"][i].tolist()):
                writer.writerow([step, "obstacle", k, x, y, z, "", "", *blank])
        yield out.getvalue()
        out.seek(0)
        out.truncate()


def _qtable_csv_lines(arrays: dict[str, NDArray[Any]]) -> Iterator[str]:
    """The Q-table as CSV, a state at a time: its label, an action's, the value, the visits;
    per-robot tables (``learning.shared_table`` false) lead each row with the robot."""
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    values, visits = arrays["values"], arrays["visits"]
    per_robot = values.ndim == 3
    writer.writerow([*(["robot"] if per_robot else []), "state", "action", "value", "visits"])
    tables = range(values.shape[0]) if per_robot else [None]
    actions = arrays["actions"].tolist()
    for r in tables:
        v, n = (values[r], visits[r]) if r is not None else (values, visits)
        lead = [r] if r is not None else []
        for i, state in enumerate(arrays["states"].tolist()):
            for a, action in enumerate(actions):
                writer.writerow([*lead, state, action, repr(float(v[i, a])), int(n[i, a])])
            yield out.getvalue()
            out.seek(0)
            out.truncate()
    if out.tell():
        yield out.getvalue()
