"""Presets, health and version."""

from __future__ import annotations

from datetime import UTC, datetime
from typing import Any

from fastapi import APIRouter, Response
from sqlalchemy.exc import SQLAlchemyError

import nanonav
from nanonav.scenario import PRESETS, preset_scenario
from nanonav.settings import Settings
from nanonav.store.deliveries import Backlog
from nanonav.store.migrate import current_revision, head_revision
from nanonav.store.queue import PRESENCE_WINDOW_S, Census
from service.deps import DeliveriesDep, SettingsDep, StoreDep
from service.schemas import Health, Queue, Version, Webhooks, Workers

router = APIRouter(tags=["meta"])


@router.get("/presets")
def list_presets() -> dict[str, dict[str, Any]]:
    """The named scenarios, fully resolved, to submit as they are or as a base."""
    return {name: preset_scenario(name).model_dump(mode="json") for name in PRESETS}


# Open to all (security.OPEN_PATHS): the empty requirement says a request may carry no key.
@router.get(
    "/healthz",
    response_model=Health,
    responses={503: {"model": Health}},
    openapi_extra={"security": [{}]},
)
def healthz(
    store: StoreDep, deliveries: DeliveriesDep, settings: SettingsDep, response: Response
) -> Health:
    """Whether the database answers, takes writes and has its schema at the newest migration;
    how many jobs wait and how many workers were seen lately; how many webhooks are due and
    when a worker last sent some.

    Webhooks due with no sender at work are told in ``note``, not as 503: the API and the
    jobs still work, and a load balancer taking the API away would help no webhook."""
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
    now = datetime.now(UTC)
    backlog = deliveries.backlog(now=now)
    window_s = sender_window_s(settings)
    notes = []
    if waiting := workers_note(census):
        notes.append(waiting)
    if stalled := _stalled_webhooks(backlog, now, window_s):
        notes.append(stalled)
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
        workers=Workers(
            seen=census.workers, preparing=census.preparing, window_s=PRESENCE_WINDOW_S
        ),
        webhooks=Webhooks(
            due=backlog.due,
            retrying=backlog.retrying,
            oldest_due_at=backlog.oldest_due_at,
            overdue_s=_age_s(backlog.oldest_due_at, now),
            last_pass_at=backlog.last_pass_at,
            window_s=window_s,
        ),
        note="; ".join(notes) or None,
    )


def workers_note(census: Census) -> str | None:
    """What /healthz and the dashboard say when no worker takes jobs: those preparing the
    engine, or none seen (with jobs waiting or not); None while a worker is ready."""
    if census.workers:
        return None
    if census.preparing:
        workers = "1 worker is" if census.preparing == 1 else f"{census.preparing} workers are"
        return (
            f"{workers} preparing the engine (a first start compiles it: about a minute); "
            "queued jobs wait for it"
        )
    if census.queued:
        jobs = "1 job is" if census.queued == 1 else f"{census.queued} jobs are"
        return (
            f"{jobs} queued but no worker has been seen in the last {PRESENCE_WINDOW_S:g} s: "
            "start one with `nanonav worker`"
        )
    return (
        f"no worker has been seen in the last {PRESENCE_WINDOW_S:g} s, so a job submitted now "
        "waits: start one with `nanonav worker`"
    )


def sender_window_s(settings: Settings) -> float:
    """How long a webhook sender may go without progress and still count as sending: it
    records progress every few seconds between tries, and one try may wait out a connect, a
    write and a read timeout."""
    return PRESENCE_WINDOW_S + 3 * settings.webhook_timeout_s


def _stalled_webhooks(backlog: Backlog, now: datetime, window_s: float) -> str | None:
    """What to say of webhooks that are due while no sender has made progress lately."""
    if not backlog.due:
        return None
    passed_s = _age_s(backlog.last_pass_at, now)
    if passed_s is not None and passed_s <= window_s:
        return None
    overdue_s = _age_s(backlog.oldest_due_at, now) or 0.0
    due = "1 webhook is" if backlog.due == 1 else f"{backlog.due} webhooks are"
    last = "" if passed_s is None else f" (the last one {passed_s:.0f} s ago)"
    return (
        f"{due} due (the oldest for {overdue_s:.0f} s) but no worker has sent webhooks in the "
        f"last {window_s:g} s{last}: start a worker with the API's NANONAV_WEBHOOK_* settings, "
        "or read the log of the one that should send them"
    )


def _age_s(moment: datetime | None, now: datetime) -> float | None:
    return None if moment is None else max((now - moment).total_seconds(), 0.0)


@router.get("/version", response_model=Version)
def version() -> Version:
    """The running code's version."""
    return Version(name="nanonav", version=nanonav.__version__)
