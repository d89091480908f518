"""The app factory: ``uvicorn --factory service.app:create_app``."""

from __future__ import annotations

import asyncio
import gc
from collections.abc import AsyncIterator
from contextlib import asynccontextmanager
from functools import cache, partial
from pathlib import Path

from fastapi import Depends, FastAPI, Security
from fastapi.middleware.cors import CORSMiddleware
from fastapi.staticfiles import StaticFiles

import nanonav
from nanonav.settings import Settings
from nanonav.store import JobStore, PolicyNotFound, StudyStore
from nanonav.store.deliveries import DeliveryStore
from nanonav.store.revocations import RevocationStore
from service import problems
from service.caching import ETags
from service.drawing import Drawer
from service.events import Poller, StreamLimits
from service.limits import BodySizeLimit
from service.methods import HeadAsGet
from service.orphans import stop_when_orphaned
from service.reports import Reports
from service.routes import events, jobs, meta, pages, policies, studies
from service.security import (
    BEARER,
    CORS_EXPOSED_HEADERS,
    CORS_METHODS,
    CORS_REQUEST_HEADERS,
    Guard,
    refuse_cross_site,
)
from service.sessions import Sessions
from service.uploads import NetworkChecks, UploadLine

STATIC = Path(__file__).resolve().parent / "static"
DESCRIPTION = """Submit nanorobot scenarios, watch them run, and fetch their results.

A dashboard for people is at `/`. `POST /jobs` queues a scenario (`{}` is all defaults); worker
processes run it. `POST /studies` queues a grid of scenarios x seeds and answers with means,
confidence intervals and paired comparisons as its jobs finish. `POST /policies` keeps a Q-table
trained elsewhere, for scenarios to evaluate as `policy_from: "policy-<id>"`. Errors are
`application/problem+json` (RFC 9457); a 422 names the offending fields. Text sent to be kept
may hold any character but U+0000 (NUL), refused with a 422 `nul_character` naming where.
"""


@cache
def _collect_once() -> None:
    """A full collection before the first app a process serves freezes what it holds, so that
    no garbage is kept. An app served after another in the same process (the tests serve
    hundreds) freezes without it: the walk over everything took 0.13 s idle, and 0.5-1 s in a
    test process beside two others, at every start."""
    gc.collect()


# long: the app assembled in one place: settings, store, middleware, routes, lifespan
def create_app(settings: Settings | None = None) -> FastAPI:
    """The API over the store that ``settings`` (by default the environment's) names."""
    settings = settings or Settings()
    store = JobStore.from_url(settings.database_url, busy_timeout_s=settings.store_busy_timeout_s)
    study_store = StudyStore(store.engine)
    sessions = Sessions(settings, RevocationStore(store.engine))
    poller = Poller(settings.events_poll_s)

    @asynccontextmanager
    async def lifespan(app: FastAPI) -> AsyncIterator[None]:
        # Everything imported and built so far lives as long as the process: the garbage
        # collector's full passes skip it instead of walking it again (under load each walk
        # stalled every request for 100-150 ms).
        _collect_once()
        gc.freeze()
        poller.start()
        orphan_check = asyncio.create_task(stop_when_orphaned(), name="orphan-check")
        try:
            yield
        finally:
            orphan_check.cancel()
            await poller.stop()
            store.close()
            gc.unfreeze()  # an app served in a process that goes on (tests) can be collected

    keyed = bool(settings.api_keys)
    app = FastAPI(
        title="NanoNav",
        version=nanonav.__version__,
        description=DESCRIPTION,
        lifespan=lifespan,
        docs_url=None,  # served by the dashboard, with its assets local
        redoc_url=None,
        # Writes another site may have forged are refused; with keys, the OpenAPI document says
        # so (Swagger UI's "Authorize"), and Guard checks them.
        dependencies=[
            Depends(refuse_cross_site),
            *([Security(BEARER)] if settings.api_keys else []),
        ],
        responses=problems.problems(401) if keyed else None,
    )
    app.state.settings = settings
    app.state.store = store
    app.state.studies = study_store
    app.state.reports = Reports()
    # networks sent as policies are checked each in a process of its own, this many at once
    app.state.network_checks = NetworkChecks(
        settings.network_checks_at_once, settings.network_checks_waiting
    )
    app.state.deliveries = DeliveryStore(store.engine)
    app.state.sessions = sessions
    app.state.poller = poller
    app.state.job_events = poller.channel(partial(events.job_snapshots, store))
    app.state.study_events = poller.channel(partial(events.study_snapshots, study_store))
    app.state.streams = StreamLimits(
        settings.events_streams_per_key, settings.events_streams_per_process
    )
    app.state.drawer = Drawer(settings.drawing_queue)
    app.add_middleware(BodySizeLimit, max_bytes=settings.max_body_bytes)
    app.add_middleware(ETags)
    app.add_middleware(HeadAsGet)
    app.add_middleware(UploadLine, checks=app.state.network_checks)
    app.add_middleware(Guard, settings=settings, sessions=sessions)
    if settings.allowed_origins:
        # Pages of the allowed origins may call the API from a browser: their preflights are
        # answered outside Guard, since a browser never sends the key with a preflight.
        app.add_middleware(
            CORSMiddleware,
            allow_origins=settings.allowed_origins,
            allow_methods=CORS_METHODS,
            allow_headers=CORS_REQUEST_HEADERS,
            expose_headers=CORS_EXPOSED_HEADERS,
        )
    problems.install(app)
    app.add_exception_handler(events.NothingNew, events.nothing_new)
    app.add_exception_handler(PolicyNotFound, policies.policy_not_found)
    app.include_router(jobs.router)
    app.include_router(studies.router)
    app.include_router(policies.router)
    app.include_router(events.router)
    app.include_router(meta.router)
    app.include_router(pages.router)
    app.mount("/static", StaticFiles(directory=STATIC), name="static")
    return app
