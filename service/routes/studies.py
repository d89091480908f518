"""Studies: a grid of scenarios x seeds in one request, their statistics, table and pictures."""

from __future__ import annotations

import json
from collections.abc import Mapping
from dataclasses import dataclass
from functools import cache, lru_cache, partial
from typing import Annotated, Any, Literal

from fastapi import APIRouter, Body, Path, Query, Response
from fastapi.concurrency import run_in_threadpool
from pydantic import ValidationError

from nanonav.pictures import study as pictures
from nanonav.status import FINISHED
from nanonav.store import (
    JobStore,
    StudyJob,
    StudyJobState,
    StudyNotFound,
    StudyRecord,
    StudyStore,
    policy_name,
)
from nanonav.studies import export
from nanonav.studies.report import (
    JobOutcome,
    StudyStatus,
    comparison_columns,
    comparison_table,
    report,
    status_counts,
    status_of,
    table,
    table_columns,
)
from nanonav.studies.spec import StudySpec, grid_index, point_values, points
from service.budget import check_budget, check_quota_fits
from service.caching import IMMUTABLE
from service.callbacks import CallbackUrl, callback_answer, check_callback
from service.deps import (
    DeliveriesDep,
    DrawerDep,
    JsonBody,
    ReportsDep,
    SettingsDep,
    StoreDep,
    StudiesDep,
)
from service.drawing import Drawer, kept_name
from service.idempotency import IdempotencyDep
from service.ids import StudyId
from service.paging import Cursor, decode_cursor, encode_cursor
from service.policy_from import check_policy_from, policies_kept
from service.problems import (
    InvalidInput,
    NoCallback,
    NoMetric,
    NothingToRetry,
    StudyFinished,
    field_error,
    invalid_body,
    problems,
)
from service.reports import Reports
from service.routes.jobs import PNG
from service.schemas import Callback, JobCounts, Study, StudyLinks, StudyPage, StudySummary
from service.security import SCRIPTED_ONLY, CallerDep, owned_tables, quota_of

router = APIRouter(prefix="/studies", tags=["studies"])

PictureName = Annotated[
    str,
    Path(
        pattern="^(" + "|".join(pictures.PICTURES) + ")$",
        description="A metric (" + ", ".join(pictures.PICTURES[:-3]) + "), 'learning', "
        "'policies' (a study whose points learn Q-tables), or 'training' (a study whose points "
        "train networks).",
    ),
]

STUDY_EXAMPLES: dict[str, Any] = {
    "policies": {
        "summary": "Q-learning against gradient climbing as obstacles get denser",
        "value": {
            "name": "policy x obstacles",
            "base": {"preset": "paper-single", "learning": {"episodes": 20}},
            "grid": {"robots.policy": ["q_learning", "gradient"], "obstacles.count": [0, 10, 30]},
            "replicates": 10,
            "compare": "robots.policy",
        },
    },
}


@router.post(
    "",
    status_code=202,
    response_model=Study,
    dependencies=[JsonBody],
    responses=problems(400, 403, 413, 415, 422, 429),
)
def submit_study(
    spec: Annotated[StudySpec, Body(openapi_examples=STUDY_EXAMPLES)],
    studies: StudiesDep,
    reports: ReportsDep,
    store: StoreDep,
    settings: SettingsDep,
    caller: CallerDep,
    response: Response,
    idempotency: IdempotencyDep,
    callback_url: CallbackUrl = None,
) -> Study:
    """Queue every grid point x seed as a job, all in one transaction, after validating all.

    A study the schema allows may still be refused with 422, each error typed by its rule:
    ``study_rule`` (a base or grid point that is not a valid scenario, or ``compare`` not a
    grid key with two values), ``too_many_jobs`` (more grid points x seeds than the server
    takes), and as in POST /jobs ``budget_exceeded``, ``policy_unusable``, ``refused``,
    ``idempotency_key``, ``idempotency_key_reused``, ``nul_character`` and
    ``quota_never_fits`` (more jobs or robot-steps than the caller's quota allows even with
    nothing else active)."""
    check_callback(callback_url, settings)
    if spec.job_count > settings.study_max_jobs:
        detail = (
            f"the study makes {spec.job_count} jobs (grid points x seeds), over the "
            f"{settings.study_max_jobs} a study may make"
        )
        given = "seeds" if spec.seeds is not None else "replicates"
        raise InvalidInput(
            detail,
            [field_error(["body", key], detail, "too_many_jobs") for key in ("grid", given)],
        )
    try:
        grid = points(spec)
    except ValidationError as error:
        raise invalid_body(error) from None
    read = cache(owned_tables(store, caller))  # points that name the same job read its table once
    counted: dict[bytes, int] = {}  # points that name the same network count it once
    for point in grid:
        blame = [("body", "grid", k, grid_index(spec, k, v)) for k, v in point.values.items()]
        multiply_adds = check_policy_from(
            point.scenario, read, *_policy_blame(spec, point.values), settings=settings,
            counted=counted,
        )  # fmt: skip
        check_budget(point.scenario, settings, blame or None, multiply_adds)
    seeds = spec.seed_list
    quota = quota_of(caller, settings)
    size = [("body", "grid"), ("body", "seeds" if spec.seeds is not None else "replicates")]
    steps = sum(point.scenario.robot_steps_budget for point in grid) * len(seeds)
    check_quota_fits(quota, jobs=spec.job_count, robot_steps=steps, blame=size)
    jobs = [
        StudyJob(
            scenario=point.with_seed(seed).model_dump(mode="json"),
            robot_steps=point.scenario.robot_steps_budget,
            episodes=point.scenario.episodes,
            point=point.index,
            seed=seed,
        )
        # Seed by seed: a study stopped half-way has whole seeds at every point, to pair.
        for seed in seeds
        for point in grid
    ]
    stored = spec.model_copy(update={"seeds": seeds, "replicates": None})

    def naming(policy_id: int) -> tuple[tuple[str | int, ...], str]:
        named = next(p for p in grid if p.scenario.policy_from == policy_name(policy_id))
        return _policy_blame(spec, named.values)

    with policies_kept(naming):
        record = studies.create(
            name=spec.name,
            spec=stored.model_dump(mode="json"),
            jobs=jobs,
            idempotency=idempotency,
            callback_url=callback_url,
            owner=caller.owner,
            quota=quota,
        )
    response.headers["Location"] = f"/studies/{record.id}"
    return study_answer(studies, reports, record)


@router.get("", response_model=StudyPage, responses=problems(422))
def list_studies(
    studies: StudiesDep,
    caller: CallerDep,
    limit: Annotated[int, Query(ge=1, le=100, description="Studies per page.")] = 20,
    cursor: Cursor = None,
) -> StudyPage:
    """A page of studies, newest first; with API keys, only the caller's own."""
    before = None if cursor is None else decode_cursor(cursor)
    page = studies.page(limit=limit, before_id=before, owner=caller.only)
    counts = studies.counts([s.id for s in page.studies])
    summaries = []
    for record in page.studies:
        found = {status.value: n for status, n in counts[record.id].items()}
        jobs = JobCounts.of(found)
        summaries.append(
            StudySummary(
                id=record.id,
                name=record.name,
                status=status_of(found, record.cancel_requested),
                created_at=record.created_at,
                cancel_requested=record.cancel_requested,
                jobs=jobs,
                links=_links(
                    record.id,
                    (
                        *pictures.EVERY_STUDYS_PICTURES,
                        *pictures.learner_pictures(*learners(record.spec)),
                    ),
                ),
            )
        )
    next_cursor = None if page.next_before_id is None else encode_cursor(page.next_before_id)
    return StudyPage(
        studies=summaries,
        next_cursor=next_cursor,
        next=None if next_cursor is None else f"/studies?limit={limit}&cursor={next_cursor}",
    )


@router.get("/{study_id}", response_model=Study, responses=problems(404, 422))
def get_study(study_id: StudyId, studies: StudiesDep, reports: ReportsDep) -> Study:
    """A study's jobs per status and, per grid point and metric, mean and 95% CI; with
    `compare`, paired differences seed by seed."""
    return study_answer(studies, reports, studies.get(study_id))


@router.get("/{study_id}/callback", response_model=Callback, responses=problems(404, 422))
def get_study_callback(
    study_id: StudyId, studies: StudiesDep, deliveries: DeliveriesDep
) -> Callback:
    """The webhook the study sends when its last job ends, and how sending it went."""
    studies.get(study_id)
    record = deliveries.for_study(study_id)
    if record is None:
        raise NoCallback(f"study {study_id} was submitted without a callback_url")
    return callback_answer(record)


@router.post(
    "/{study_id}/cancel",
    response_model=Study,
    responses=problems(403, 404, 409, 415, 422),
    openapi_extra=SCRIPTED_ONLY,
)
def cancel_study(study_id: StudyId, studies: StudiesDep, reports: ReportsDep) -> Study:
    """Cancel a study's unfinished jobs: queued ones at once, running ones within a second.

    The rule of a job's cancel: 200 when the study is or will be cancelled, 409 when it
    already ended another way (every job succeeded or failed)."""
    view = study_answer(studies, reports, studies.get(study_id))
    if view.status in FINISHED and not view.cancel_requested:
        raise StudyFinished(f"study {study_id} has already finished: it is {view.status}")
    return study_answer(studies, reports, studies.cancel(study_id))


@router.post(
    "/{study_id}/retry",
    response_model=Study,
    responses=problems(403, 404, 409, 415, 422, 429),
    openapi_extra=SCRIPTED_ONLY,
)
def retry_study(
    study_id: StudyId,
    studies: StudiesDep,
    reports: ReportsDep,
    settings: SettingsDep,
    caller: CallerDep,
) -> Study:
    """Queue every failed job of the study again, in one request: each runs anew (its
    attempts, error and partial result cleared) on the same scenario and seed, so the study's
    pairing by seed holds. Its report and pictures are made again from its jobs once they end.

    409 when no job of it has failed; 429 past the caller's quota, which counts the jobs
    queued again. A callback_url the study gave that was already sent is not sent again."""
    if not studies.retry_failed(study_id, quota=quota_of(caller, settings)):
        raise NothingToRetry(f"no job of study {study_id} has failed: there is nothing to retry")
    return study_answer(studies, reports, studies.get(study_id))


@router.delete(
    "/{study_id}",
    status_code=204,
    response_class=Response,
    responses={204: {"description": "Deleted."}, **problems(403, 404, 409, 415, 422)},
    openapi_extra=SCRIPTED_ONLY,
)
def delete_study(study_id: StudyId, studies: StudiesDep) -> Response:
    """Delete an ended study with its jobs, their results, its report and its pictures.

    409 while any of its jobs is queued or running (cancel it first); 404 once it is gone."""
    studies.delete(study_id)
    return Response(status_code=204)


@router.get(
    "/{study_id}/results.csv",
    response_class=Response,
    responses={
        200: {
            "content": {"text/csv": {}, export.PARQUET_MEDIA_TYPE: {}},
            "description": "A row per job: id, seed, grid values, status, metrics.",
        },
        **problems(404, 422),
    },
)
def get_results(
    study_id: StudyId,
    studies: StudiesDep,
    format: Annotated[Literal["csv", "parquet"], Query()] = "csv",
) -> Response:
    """The study's table, a row per job (metrics empty unless the job succeeded)."""
    loaded = _Loaded.of(studies, studies.get(study_id))
    rows = table(point_values(loaded.spec), loaded.outcomes)
    columns = table_columns(loaded.spec, loaded.outcomes)
    return _table_file(f"nanonav-study-{study_id}", format, columns, rows, done=loaded.done)


@router.get(
    "/{study_id}/comparisons.csv",
    response_class=Response,
    responses={
        200: {
            "content": {"text/csv": {}, export.PARQUET_MEDIA_TYPE: {}},
            "description": "A row per paired difference: the other grid values, the method "
            "and its baseline, the metric, n, the mean difference with its 95% interval, "
            "p_value beside p_holm and holm_comparisons, and resolvable.",
        },
        **problems(404, 422),
    },
)
def get_comparisons(
    study_id: StudyId,
    studies: StudiesDep,
    reports: ReportsDep,
    format: Annotated[Literal["csv", "parquet"], Query()] = "csv",
) -> Response:
    """The study's paired comparisons as a table, as GET /studies/{id} reports them (no rows
    unless the study compares): each p-value beside Holm's adjustment of it, for a paper's
    table. The report is the kept one, or the one polls share: no job is read for it."""
    study = study_answer(studies, reports, studies.get(study_id))
    spec = StudySpec.model_validate(study.spec)
    rows = comparison_table(spec, study.model_dump(include={"comparisons"}))
    name = f"nanonav-study-{study_id}-comparisons"
    done = study.status in FINISHED
    return _table_file(name, format, comparison_columns(spec), rows, done=done)


def _table_file(
    name: str,
    format: Literal["csv", "parquet"],
    columns: list[str],
    rows: list[dict[str, Any]],
    *,
    done: bool,
) -> Response:
    """A table as the file asked for, named ``name``; a finished study's never changes, an
    unfinished one's is asked for again."""
    caching = IMMUTABLE if done else {}
    if format == "parquet":
        return Response(
            export.to_parquet(columns, rows),
            media_type=export.PARQUET_MEDIA_TYPE,
            headers={"Content-Disposition": f'attachment; filename="{name}.parquet"', **caching},
        )
    return Response(
        export.to_csv(columns, rows),
        media_type="text/csv; charset=utf-8",
        headers={"Content-Disposition": f'attachment; filename="{name}.csv"', **caching},
    )


@router.get(
    "/{study_id}/plots/{name}.png",
    response_class=Response,
    responses={**PNG, **problems(404, 422, 503)},
)
async def get_study_plot(
    study_id: StudyId, name: PictureName, studies: StudiesDep, store: StoreDep, drawer: DrawerDep
) -> Response:
    """A metric against the swept numeric parameter with CI bars, a line per compared method
    (grouped bars when no swept parameter is numeric), the mean learning curves, or the
    policies its points learned (the greedy action in their most visited states, counted over
    seeds, with the action gap), or the training curves of the networks its points train
    against the decisions trained, every other point a level of its evaluation. 404 for one
    of the swarm's metrics while no job of the study has it, for policies where no point
    learns, and for training where none trains (its links name those it has)."""
    png = await run_in_threadpool(studies.plot, study_id, kept_name(name, pictures.VERSION))
    if png is not None:
        return Response(png, media_type="image/png", headers=IMMUTABLE)
    return await _draw(drawer, studies, store, study_id, name)


async def _draw(
    drawer: Drawer, studies: StudyStore, store: JobStore, study_id: int, name: str
) -> Response:
    finished: list[bool] = []
    png = await drawer.draw(
        ("study", study_id, name), partial(_draw_now, studies, store, study_id, name, finished)
    )
    headers = IMMUTABLE if finished and finished[0] else {"Cache-Control": "no-cache"}
    return Response(png, media_type="image/png", headers=headers)


def _draw_now(
    studies: StudyStore, store: JobStore, study_id: int, name: str, finished: list[bool]
) -> bytes:
    loaded = _Loaded.of(studies, studies.get(study_id), curves=name in ("learning", "training"))
    if name == "learning":
        png = pictures.learning_png(loaded.spec, point_values(loaded.spec), loaded.outcomes)
    elif name == "training":
        if not pictures.training_points(loaded.spec):
            raise NoMetric(
                f"no point of study {study_id} trains a network: only robots.policy ppo and "
                "recurrent_ppo do"
            )
        png = pictures.training_png(loaded.spec, point_values(loaded.spec), loaded.outcomes)
    elif name == "policies":
        learning = set(pictures.learning_points(loaded.spec))
        if not learning:
            raise NoMetric(
                f"no point of study {study_id} learns a Q-table: only q_learning trained for "
                "at least one episode does"
            )
        learned = [j for j in loaded.outcomes if j.point in learning and j.status == "succeeded"]
        kept = store.qtables([j.job_id for j in learned])
        tables: dict[int, list[dict[str, Any]]] = {}
        for job in learned:
            tables.setdefault(job.point, []).append(kept.get(job.job_id, {}))
        png = pictures.policies_png(loaded.spec, point_values(loaded.spec), tables)
    else:
        found = loaded.report(studies)
        if name not in pictures.pictures_of(found):
            raise NoMetric(
                f"no job of study {study_id} reports {name}: only runs whose robots take up "
                "space, treat cells or signal do"
            )
        png = pictures.metric_png(loaded.spec, found, name)
    if loaded.done:  # kept under its drawing's version: a copy of an older one is drawn again
        studies.keep_plot(study_id, kept_name(name, pictures.VERSION), png)
    finished.append(loaded.done)
    return png


@dataclass(frozen=True)
class _Loaded:
    """A study with its jobs' states, as read in one go."""

    record: StudyRecord
    spec: StudySpec
    states: list[StudyJobState]
    outcomes: list[JobOutcome]
    status: StudyStatus

    @classmethod
    def of(cls, studies: StudyStore, record: StudyRecord, *, curves: bool = False) -> _Loaded:
        states = studies.job_states(record.id, curves=curves)
        outcomes = [
            JobOutcome(s.job_id, s.point, s.seed, s.status.value, s.metrics, s.curve)
            for s in states
        ]
        status = status_of(status_counts(outcomes), record.cancel_requested)
        spec = StudySpec.model_validate(record.spec)
        return cls(record, spec, states, outcomes, status)

    @property
    def done(self) -> bool:
        return self.status in FINISHED

    def report(self, studies: StudyStore) -> dict[str, Any]:
        """The statistics; those of a finished study are computed once and kept."""
        if self.done and self.record.report is not None:
            return self.record.report
        found = report(self.spec, point_values(self.spec), self.outcomes)
        if self.done:
            studies.keep_report(self.record.id, found)
        return found


def study_answer(studies: StudyStore, reports: Reports, record: StudyRecord) -> Study:
    """The study as GET /studies/{id} answers it. Its counts and progress are one aggregate,
    always current; its report is read from the finished study, or taken from ``reports``
    (while the study runs, at most about a second behind its counts), so that polling a large
    study costs no job's metrics."""
    found = studies.progress([record.id]).get(record.id)
    if found is None:
        raise StudyNotFound(record.id)
    counts = {status.value: n for status, n in found.jobs.items()}
    total = sum(counts.values())
    status = status_of(counts, found.cancel_requested)
    done = status in FINISHED
    if done and record.report is not None:
        statistics = record.report
    else:
        statistics = reports.get(
            record.id,
            found.by_point,
            lambda: _Loaded.of(studies, record).report(studies),
            exact=done,  # a finished study's statistics are its final ones
        )
    return Study(
        id=record.id,
        name=record.name,
        status=status,
        created_at=record.created_at,
        finished_at=found.last_finished_at if done else None,
        cancel_requested=found.cancel_requested,
        jobs=JobCounts.of(counts),
        progress=found.work_done / max(total, 1),
        spec=record.spec,
        links=_links(
            record.id,
            pictures.pictures_of(statistics, *learners(record.spec)),
        ),
        **statistics,
    )


def _policy_blame(spec: StudySpec, values: Mapping[str, Any]) -> tuple[tuple[str | int, ...], str]:
    """Where a grid point's policy_from comes from (the grid value or the base), and which
    point it is, to name in a refusal."""
    if "policy_from" in values:
        loc: tuple[str | int, ...] = (
            "body", "grid", "policy_from", grid_index(spec, "policy_from", values["policy_from"])
        )  # fmt: skip
    else:
        loc = ("body", "base", "policy_from")
    others = {k: v for k, v in values.items() if k != "policy_from"}
    where = f"at the grid point {others}: " if others else ""
    return loc, where


def learners(spec: Mapping[str, Any]) -> tuple[bool, bool]:
    """Whether a point of the study ``spec`` learns a Q-table (it has a policies picture),
    and whether one trains a network (it has a training picture)."""
    return _learners(json.dumps(spec, sort_keys=True))


@lru_cache(maxsize=256)
def _learners(spec: str) -> tuple[bool, bool]:
    # a study's spec never changes: its points are validated once, not on every poll
    study = StudySpec.model_validate(json.loads(spec))
    return bool(pictures.learning_points(study)), bool(pictures.training_points(study))


def _links(study_id: int, plots: tuple[str, ...]) -> StudyLinks:
    """Where the study's results are; ``plots``, the pictures it has (a list of studies, which
    reads no report, names those every study has: the swarm's metrics are named by the study
    itself once a job has them)."""
    base = f"/studies/{study_id}"
    return StudyLinks(
        self_=base,
        cancel=f"{base}/cancel",
        jobs=f"/jobs?study={study_id}",
        results_csv=f"{base}/results.csv",
        results_parquet=f"{base}/results.csv?format=parquet",
        comparisons_csv=f"{base}/comparisons.csv",
        plots={name: f"{base}/plots/{name}.png" for name in plots},
    )
