"""Presets, health and version."""

from __future__ import annotations

from typing import Any

from fastapi import APIRouter, Response
from sqlalchemy.exc import SQLAlchemyError

import nanonav
from nanonav.scenario import PRESETS, preset_scenario
from nanonav.store.migrate import current_revision, head_revision
from nanonav.store.queue import PRESENCE_WINDOW_S
from service.deps import StoreDep
from service.schemas import Health, Queue, Version, Workers

router = APIRouter(tags=["meta"])


@router.get("/presets")
def list_presets() -> dict[str, dict[str, Any]]:
    """The named scenarios, fully resolved, to submit as they are or as a base."""
    return {name: preset_scenario(name).model_dump(mode="json") for name in PRESETS}


@router.get("/healthz", response_model=Health, responses={503: {"model": Health}})
def healthz(store: StoreDep, response: Response) -> Health:
    """Whether the database answers, takes writes and has its schema at the newest migration;
    how many jobs wait and how many workers were seen lately."""
    head = head_revision()
    try:
        revision = current_revision(store.engine)
    except SQLAlchemyError:
        response.status_code = 503
        return Health(status="unavailable", database=False, revision=None, head=head)
    if revision != head or not store.writable():
        response.status_code = 503
        return Health(status="unavailable", database=True, revision=revision, head=head)
    census = store.census(seen_within_s=PRESENCE_WINDOW_S)
    note = None
    if census.queued and not census.workers:
        note = (
            f"{census.queued} jobs are queued but no worker has been seen in the last "
            f"{PRESENCE_WINDOW_S:g} s: start one with `nanonav worker`"
        )
    return Health(
        status="ok",
        database=True,
        revision=revision,
        head=head,
        queue=Queue(
            queued=census.queued,
            running=census.running,
            oldest_queued_at=census.oldest_queued_at,
        ),
        workers=Workers(seen=census.workers, window_s=PRESENCE_WINDOW_S),
        note=note,
    )


@router.get("/version", response_model=Version)
def version() -> Version:
    """The running code's version."""
    return Version(name="nanonav", version=nanonav.__version__)
