"""The dashboard: server-rendered pages over the same store as the JSON API.

Pages that only show results read without JavaScript; forms and live progress use a little of
it (``service/static``), talking to the JSON API like any client. Third-party browser code (the
3-D plotting library, the OpenAPI page's assets) comes from installed Python packages, served
here, so the dashboard works offline.
"""

from __future__ import annotations

import json
import math
import time
from importlib import resources
from pathlib import Path
from typing import Annotated, Any, get_args

from fastapi import APIRouter, Depends, Query, Request
from fastapi import Path as PathParam
from fastapi.openapi.docs import get_swagger_ui_html
from fastapi.responses import FileResponse, HTMLResponse, RedirectResponse, Response
from fastapi.templating import Jinja2Templates
from pydantic import BaseModel, ConfigDict, Field

from nanonav import table1
from nanonav.pictures import job as job_pictures
from nanonav.policy import evaluation_scenario
from nanonav.scenario import (
    PRESETS,
    ActionSet,
    CommunicationModel,
    FieldModel,
    Policy,
    Scenario,
)
from nanonav.store import (
    JobNotFound,
    JobStatus,
    JobStore,
    PolicyNotFound,
    PolicyRecord,
    StudyNotFound,
)
from nanonav.store.policies import NETWORK, policy_number
from nanonav.store.queue import PRESENCE_WINDOW_S
from nanonav.studies.spec import GRID_KEYS
from service.deps import ReportsDep, SessionsDep, SettingsDep, StoreDep, StudiesDep
from service.json_keys import refuse_duplicate_keys
from service.numerals import positive_int
from service.paging import Cursor, decode_cursor, encode_cursor
from service.problems import Unauthorized
from service.reports import Reports
from service.routes.meta import workers_note
from service.routes.policies import get_policy
from service.routes.studies import list_studies, study_answer
from service.schemas import Job
from service.security import (
    Caller,
    CallerDep,
    caller_of,
    matching_key,
    owner_of,
    presented_session,
)
from service.sessions import cleared_cookie, same_site_path, session_cookie
from service.waiting import waiting_for

router = APIRouter(include_in_schema=False)
templates = Jinja2Templates(directory=Path(__file__).resolve().parents[1] / "templates")

# Browser code shipped inside installed packages: the name it is served under, and where it is.
VENDOR: dict[str, tuple[str, str]] = {
    "plotly.min.js": ("plotly", "package_data/plotly.min.js"),
    "swagger-ui-bundle.js": ("fastapi_offline", "static/swagger-ui-bundle.js"),
    "swagger-ui.css": ("fastapi_offline", "static/swagger-ui.css"),
    "swagger-favicon.png": ("fastapi_offline", "static/favicon.png"),
}
# The interactive 3-D view draws at most this many rows of the trajectory.
VIEW_ROWS = 400
# A study's table shows these metrics, those it reports (its CSV has them all); the swarm's
# only once a job has them.
STUDY_COLUMNS = ("success_rate", "total_steps", "final_distance", "average_distance",
                 "average_concentration", "collisions", "path_efficiency", "treated_fraction",
                 "time_to_treat_all", "never_delivered", "robots_per_cell",
                 "most_robots_on_a_cell", "bumps")  # fmt: skip
# And charts these, of those it reports, beside its learning curves.
STUDY_PICTURES = ("success_rate", "total_steps", "average_distance", "treated_fraction",
                  "time_to_treat_all", "never_delivered")  # fmt: skip
# A page's id is read as the API reads one (``service.ids``): plain digits, or no such page.
PageId = Annotated[str, PathParam(max_length=40)]


def _page(request: Request, name: str, status: int = 200, **context: Any) -> HTMLResponse:
    store = request.app.state.store
    census = store.census(seen_within_s=PRESENCE_WINDOW_S)
    note = workers_note(census)
    health = {"queued": census.queued, "running": census.running, "workers": census.workers,
              "preparing": census.preparing, "window_s": PRESENCE_WINDOW_S,
              "note": note and f"{note}."}  # fmt: skip
    signed_in = caller_of(request).scoped  # with keys, a page shown is a page logged in to
    return templates.TemplateResponse(
        request, name, {"health": health, "signed_in": signed_in, **context}, status_code=status
    )


def _missing(request: Request, what: str) -> HTMLResponse:
    return _page(request, "missing.html", status=404, what=what)


def _named(kind: str, spelled: str) -> str:
    """What a missing page names: ``job 7``, or ``job '+7'`` for an id not in plain digits."""
    return f"{kind} {spelled}" if positive_int(spelled) else f"{kind} {spelled!r}"


def _form_choices() -> dict[str, Any]:
    return {
        "presets": sorted(PRESETS),
        "policies": get_args(Policy),
        "action_sets": get_args(ActionSet),
        "field_models": get_args(FieldModel),
        "communication_models": get_args(CommunicationModel),
    }


def _visible_job(store: JobStore, caller: Caller, job_id: int) -> Job | None:
    """The job, if it exists and the caller may see it."""
    try:
        record = store.get(job_id)
    except JobNotFound:
        return None
    if caller.scoped and record.owner != caller.owner:
        return None
    return Job.of(record, waiting_for=waiting_for(record, store))


@router.get("/", response_class=HTMLResponse)
def index(
    request: Request,
    store: StoreDep,
    studies: StudiesDep,
    caller: CallerDep,
    from_: Annotated[str, Query(alias="from", max_length=20)] = "",
    policy: Annotated[str, Query(max_length=20)] = "",
) -> HTMLResponse:
    """The new-job form (filled in from job ``from``, or to evaluate ``policy``, if given);
    recent studies and lone jobs."""
    source_id, policy_id = positive_int(from_), positive_int(policy)
    source = None if source_id is None else _visible_job(store, caller, source_id)
    evaluated = None if policy_id is None else _visible_policy(store, caller, policy_id)
    unknown = [
        f"There is no {_named(kind, given)} to fill the form in from: it holds the defaults."
        for kind, given, found in (("job", from_, source), ("policy", policy, evaluated))
        if given and found is None
    ]
    form = (
        evaluation_scenario(evaluated, _observation(store, evaluated))
        if evaluated
        else source.scenario
        if source
        else None
    )
    page = store.page(status=None, limit=10, before_id=None, owner=caller.only, standalone=True)
    jobs = [Job.of(j) for j in page.jobs]
    recent = list_studies(studies, caller, limit=5).studies
    return _page(
        request, "index.html", nav="new", jobs=jobs, studies=recent, source=source,
        evaluated=evaluated, unknown=unknown, headlines=store.headlines([j.id for j in jobs]),
        form_json=json.dumps(form, indent=2) if form else "{}", **_form_choices(),
    )  # fmt: skip


def _observation(store: JobStore, policy: PolicyRecord) -> list[str] | None:
    """What a network observes (None for a table, or one deleted since it was read)."""
    if policy.kind != NETWORK:
        return None
    try:
        labels: list[str] = store.policies.table(policy.id)["observation"].tolist()
    except PolicyNotFound:
        return None
    return labels


def _visible_policy(store: JobStore, caller: Caller, policy_id: int) -> PolicyRecord | None:
    """The policy, if it exists and the caller may see it."""
    try:
        record = store.policies.get(policy_id)
    except PolicyNotFound:
        return None
    if caller.scoped and record.owner != caller.owner:
        return None
    return record


@router.get("/ui/policies", response_class=HTMLResponse)
def policies_page(
    request: Request, store: StoreDep, caller: CallerDep, cursor: Cursor = None
) -> HTMLResponse:
    """Policies sent to ``POST /policies``, newest first, each with the form that evaluates it."""
    before = None if cursor is None else decode_cursor(cursor)
    page = store.policies.page(limit=25, before_id=before, owner=caller.only)
    next_url = None
    if page.next_before_id is not None:
        next_url = f"/ui/policies?cursor={encode_cursor(page.next_before_id)}"
    return _page(
        request, "policies.html", nav="policies", policies=page.policies, next=next_url,
        first="/ui/policies" if cursor else None,
    )  # fmt: skip


@router.get("/ui/policies/{policy_id}", response_class=HTMLResponse)
def policy_page(
    request: Request, policy_id: PageId, store: StoreDep, caller: CallerDep
) -> HTMLResponse:
    """A policy: what it chooses among and from, its greedy table or its network's labels, the
    downloads, and the form that evaluates it."""
    number = positive_int(policy_id)
    record = None if number is None else _visible_policy(store, caller, number)
    if number is None or record is None:
        return _missing(request, _named("policy", policy_id))
    try:
        policy = get_policy(number, store)
    except PolicyNotFound:  # deleted since it was read
        return _missing(request, _named("policy", policy_id))
    return _page(request, "policy.html", nav="policies", policy=policy)


@router.get("/ui/jobs", response_class=HTMLResponse)
def jobs_page(
    request: Request,
    store: StoreDep,
    caller: CallerDep,
    status: Annotated[str, Query(max_length=16)] = "",
    policy: Annotated[str, Query(max_length=32)] = "",
    study: Annotated[str, Query(max_length=20)] = "",
    cursor: Cursor = None,
) -> HTMLResponse:
    """Jobs, newest first, filtered by status, policy and study (unknown values are ignored)."""
    wanted_status = JobStatus(status) if status in {s.value for s in JobStatus} else None
    wanted_policy = policy if policy in get_args(Policy) else None
    wanted_study = positive_int(study)
    before = None if cursor is None else decode_cursor(cursor)
    page = store.page(
        status=wanted_status, limit=25, before_id=before, study_id=wanted_study,
        policy=wanted_policy, owner=caller.only,
    )  # fmt: skip
    filters = {"status": wanted_status.value if wanted_status else "",
               "policy": wanted_policy or "", "study": wanted_study}  # fmt: skip
    query = "&".join(f"{k}={v}" for k, v in filters.items() if v)
    next_url = None
    if page.next_before_id is not None:
        next_url = (
            f"/ui/jobs?{query}{'&' if query else ''}cursor={encode_cursor(page.next_before_id)}"
        )
    jobs = [Job.of(j) for j in page.jobs]
    return _page(
        request, "jobs.html", nav="jobs", jobs=jobs,
        headlines=store.headlines([j.id for j in jobs]),
        filters=filters, statuses=[s.value for s in JobStatus], policies=get_args(Policy),
        next=next_url, first=f"/ui/jobs?{query}" if cursor else None,
    )  # fmt: skip


@router.get("/ui/jobs/new")
def new_job_page(request: Request) -> RedirectResponse:
    """The new-job form is the home page: this path, as /ui/studies/new is a study's, leads
    there with its query (``from``, ``policy``)."""
    query = request.url.query
    return RedirectResponse("/" + (f"?{query}" if query else ""), status_code=307)


@router.get("/ui/jobs/{job_id}", response_class=HTMLResponse)
def job_page(request: Request, job_id: PageId, store: StoreDep, caller: CallerDep) -> HTMLResponse:
    """A job: its progress live, then its Table 1, pictures and 3-D paths."""
    number = positive_int(job_id)
    job = None if number is None else _visible_job(store, caller, number)
    if job is None:
        return _missing(request, _named("job", job_id))
    metrics = store.metrics(job.id) if job.status == "succeeded" else None
    stride = 1
    if metrics is not None and metrics.get("worlds"):
        length = int(metrics["worlds"][0].get("episode_steps") or 1)
        stride = max(1, math.ceil(length / VIEW_ROWS))
    return _page(
        request, "job.html", nav="jobs", job=job, metrics=metrics,
        scenario=Scenario.model_validate(job.scenario),
        finished=job.status in {"succeeded", "failed", "cancelled"},
        table=[{"label": a, "value": b, "interval": c} for a, b, c in table1.rows(metrics)]
        if metrics else [],
        stride=stride, scenario_json=json.dumps(job.scenario, indent=2),
        network=_network_of(job.scenario, metrics),
        # the drawing's version in the URL, so that no browser keeps an older drawing
        heatmap_version=job_pictures.version("heatmap_xy"),
    )  # fmt: skip


def _network_of(scenario: dict[str, Any], metrics: dict[str, Any] | None) -> int | None:
    """The id of the network a succeeded job's robots were decided by, or None: its run says
    it was decided from outside (``work.decide_calls``), its policy_from names the policy."""
    source = scenario.get("policy_from")
    if metrics is None or "decide_calls" not in (metrics.get("work") or {}):
        return None
    return policy_number(source) if isinstance(source, str) else None


@router.get("/ui/studies", response_class=HTMLResponse)
def studies_page(
    request: Request,
    studies: StudiesDep,
    caller: CallerDep,
    cursor: Cursor = None,
) -> HTMLResponse:
    """Studies, newest first, 25 a page, each with its jobs per status."""
    page = list_studies(studies, caller, limit=25, cursor=cursor)
    next_url = None if page.next_cursor is None else f"/ui/studies?cursor={page.next_cursor}"
    return _page(
        request, "studies.html", nav="studies", studies=page.studies, next=next_url,
        first="/ui/studies" if cursor else None,
    )  # fmt: skip


@router.get("/ui/studies/new", response_class=HTMLResponse)
def new_study_page(request: Request, settings: SettingsDep) -> HTMLResponse:
    """The new-study form: a base scenario, the keys to sweep and their values, the seeds."""
    return _page(
        request, "study_new.html", nav="new-study", grid_keys=list(GRID_KEYS),
        max_jobs=settings.study_max_jobs, **_form_choices(),
    )  # fmt: skip


def _study_context(
    studies: StudiesDep, reports: Reports, study_id: int, caller: Caller
) -> dict[str, Any]:
    record = studies.get(study_id)
    if caller.scoped and record.owner != caller.owner:
        raise StudyNotFound(study_id)
    study = study_answer(studies, reports, record)
    keys = list(study.spec.get("grid", {}))
    compare = study.spec.get("compare")
    done = study.jobs.succeeded + study.jobs.failed + study.jobs.cancelled
    return {
        "study": study,
        "finished": study.status in {"succeeded", "failed", "cancelled"},
        "points": [p.model_dump() for p in study.points],
        "comparisons": [c.model_dump() for c in study.comparisons],
        "keys": keys,
        "other_keys": [k for k in keys if k != compare],
        "compare": compare,
        "shown_metrics": [m for m in STUDY_COLUMNS if m in study.metrics],
        "shown_pictures": [m for m in STUDY_PICTURES if m in study.metrics],
        "fmt": lambda v: f"{v:.3g}" if abs(v) < 1000 else f"{v:,.0f}",
        "version": done,  # pictures change as jobs finish
    }


def _visible_study(
    studies: StudiesDep, reports: Reports, study_id: str, caller: Caller
) -> dict[str, Any] | None:
    """The study page's context, if ``study_id`` names a study the caller may see."""
    number = positive_int(study_id)
    try:
        return None if number is None else _study_context(studies, reports, number, caller)
    except StudyNotFound:
        return None


@router.get("/ui/studies/{study_id}", response_class=HTMLResponse)
def study_page(
    request: Request,
    study_id: PageId,
    studies: StudiesDep,
    reports: ReportsDep,
    caller: CallerDep,
) -> HTMLResponse:
    """A study: its jobs filling in live, its table with intervals and paired comparisons."""
    context = _visible_study(studies, reports, study_id, caller)
    if context is None:
        return _missing(request, _named("study", study_id))
    return _page(request, "study.html", nav="studies", **context)


@router.get("/ui/studies/{study_id}/results", response_class=HTMLResponse)
def study_results(
    request: Request,
    study_id: PageId,
    studies: StudiesDep,
    reports: ReportsDep,
    caller: CallerDep,
) -> HTMLResponse:
    """The study page's results and counts alone, for the page to refresh as jobs finish."""
    context = _visible_study(studies, reports, study_id, caller)
    if context is None:
        return _missing(request, _named("study", study_id))
    return templates.TemplateResponse(request, "_study_fragment.html", context)


@router.get("/ui/login", response_class=HTMLResponse)
def login_page(
    request: Request, settings: SettingsDep, next: Annotated[str, Query(max_length=2000)] = "/"
) -> HTMLResponse:
    """Where a person pastes an API key; once in, the page goes back to ``next`` if that is a
    path of this site, else to the dashboard."""
    target = same_site_path(next) or "/"
    context = {"next": target, "health": None, "lasts": lasting(settings.session_ttl_s)}
    return templates.TemplateResponse(request, "login.html", context)


def lasting(seconds: float) -> str:
    """A session's lifetime in words: ``8 hours``, ``1 day``, ``90 minutes``."""
    minutes = round(seconds / 60)
    for unit, size in (("day", 1440), ("hour", 60)):
        if minutes % size == 0:
            count = minutes // size
            return f"{count} {unit}{'' if count == 1 else 's'}"
    return f"{minutes} minute{'' if minutes == 1 else 's'}"


class Login(BaseModel):
    model_config = ConfigDict(extra="forbid")

    key: str = Field(min_length=1, max_length=1000, description="An API key.")


@router.post(
    "/ui/login",
    status_code=204,
    response_class=Response,
    dependencies=[Depends(refuse_duplicate_keys)],
)
def login(login: Login, request: Request, settings: SettingsDep, sessions: SessionsDep) -> Response:
    """Check the key and answer with a signed session token in an HttpOnly, SameSite=Strict
    cookie that lasts NANONAV_SESSION_TTL_S: script cannot read it, another site's requests
    do not carry it, and it is not the key."""
    keys = tuple(key.get_secret_value() for key in settings.api_keys)
    if keys and not matching_key(login.key, keys):
        raise Unauthorized("the key is not one this API accepts")
    response = Response(status_code=204)
    if keys:
        token = sessions.issue(owner_of(login.key), now=time.time())
        secure = request.url.scheme == "https"
        cookie = session_cookie(token, secure=secure, max_age_s=sessions.ttl_s)
        response.headers["Set-Cookie"] = cookie
    return response


@router.post("/ui/logout", status_code=204, response_class=Response)
def logout(request: Request, sessions: SessionsDep) -> Response:
    """End the dashboard's session on the server, in every API process, and forget its cookie;
    without a session, only the latter."""
    token = presented_session(request.headers)
    if token is not None:
        sessions.end(token, now=time.time())
    response = Response(status_code=204)
    response.headers["Set-Cookie"] = cleared_cookie()
    return response


@router.get("/static/vendor/{name}")
def vendor(name: str) -> Response:
    """Third-party browser code from an installed package, cached for a day."""
    if name not in VENDOR:
        return Response(status_code=404)
    package, inside = VENDOR[name]
    path = Path(str(resources.files(package).joinpath(inside)))
    return FileResponse(path, headers={"Cache-Control": "public, max-age=86400"})


@router.get("/docs", response_class=HTMLResponse)
def docs(request: Request) -> HTMLResponse:
    """The OpenAPI page, with its assets served here rather than from a CDN."""
    return get_swagger_ui_html(
        openapi_url=request.app.openapi_url or "/openapi.json",
        title="NanoNav API",
        swagger_js_url="/static/vendor/swagger-ui-bundle.js",
        swagger_css_url="/static/vendor/swagger-ui.css",
        swagger_favicon_url="/static/vendor/swagger-favicon.png",
    )
