"""The dependencies routes receive, declared once as ``Annotated`` aliases.

The getters are ``async``: FastAPI runs a plain ``def`` dependency on its thread pool, a hop
that costs more than the lookup and that every request would pay once per dependency.
"""

from __future__ import annotations

from typing import Annotated

from fastapi import Depends, Request

from nanonav.settings import Settings
from nanonav.store import JobStore, StudyStore
from nanonav.store.deliveries import DeliveryStore
from service.drawing import Drawer
from service.events import Channel
from service.json_keys import refuse_duplicate_keys
from service.problems import UnsupportedMediaType
from service.reports import Reports
from service.sessions import Sessions
from service.text import refuse_nul


async def _store(request: Request) -> JobStore:
    store: JobStore = request.app.state.store
    return store


async def _settings(request: Request) -> Settings:
    settings: Settings = request.app.state.settings
    return settings


async def _studies(request: Request) -> StudyStore:
    studies: StudyStore = request.app.state.studies
    return studies


async def _deliveries(request: Request) -> DeliveryStore:
    deliveries: DeliveryStore = request.app.state.deliveries
    return deliveries


async def _sessions(request: Request) -> Sessions:
    sessions: Sessions = request.app.state.sessions
    return sessions


async def _drawer(request: Request) -> Drawer:
    drawer: Drawer = request.app.state.drawer
    return drawer


async def _reports(request: Request) -> Reports:
    reports: Reports = request.app.state.reports
    return reports


async def _job_events(request: Request) -> Channel:
    channel: Channel = request.app.state.job_events
    return channel


async def _study_events(request: Request) -> Channel:
    channel: Channel = request.app.state.study_events
    return channel


async def require_json(request: Request) -> None:
    """A request body, if there is one, must be declared as JSON, with no key given twice in
    an object (``service.json_keys``); and as the route may store what the request holds, no
    text in it may hold NUL (``service.text``)."""
    if await request.body():
        media = request.headers.get("content-type", "").split(";")[0].strip().lower()
        kind, _, subtype = media.partition("/")
        if kind != "application" or not (subtype == "json" or subtype.endswith("+json")):
            raise UnsupportedMediaType(
                f"the body must be application/json, not {media or 'undeclared'}"
            )
    await refuse_duplicate_keys(request)
    await refuse_nul(request)


StoreDep = Annotated[JobStore, Depends(_store)]
SettingsDep = Annotated[Settings, Depends(_settings)]
DrawerDep = Annotated[Drawer, Depends(_drawer)]
StudiesDep = Annotated[StudyStore, Depends(_studies)]
ReportsDep = Annotated[Reports, Depends(_reports)]
DeliveriesDep = Annotated[DeliveryStore, Depends(_deliveries)]
SessionsDep = Annotated[Sessions, Depends(_sessions)]
JobEventsDep = Annotated[Channel, Depends(_job_events)]
StudyEventsDep = Annotated[Channel, Depends(_study_events)]
JsonBody = Depends(require_json)
