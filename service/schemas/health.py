"""The service's own state: its queue, workers and webhooks, and its version."""

from __future__ import annotations

from datetime import datetime
from typing import Literal

from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
)


class Queue(BaseModel):
    queued: int = Field(description="Jobs waiting for a worker.")
    running: int = Field(description="Jobs a worker holds.")
    oldest_queued_at: datetime | None = Field(description="When the longest-waiting job came.")


class Workers(BaseModel):
    seen: int = Field(
        description="Worker processes that said they were alive lately, ready to take jobs."
    )
    preparing: int = Field(
        0,
        description="Worker processes alive lately that still prepare the engine before they "
        "take a job: on a first start a worker compiles it, which takes about a minute.",
    )
    window_s: float = Field(description="How far back 'lately' reaches, in seconds.")


class Webhooks(BaseModel):
    due: int = Field(
        description="Webhooks to send now: their next try's time has come, or their job or "
        "study has ended."
    )
    retrying: int = Field(description="Webhooks due again once a failed try's backoff passed.")
    oldest_due_at: datetime | None = Field(
        description="Since when the longest-waiting of the due ones could have been sent."
    )
    overdue_s: float | None = Field(description="How long ago that was, in seconds.")
    last_pass_at: datetime | None = Field(
        description="When a worker's webhook sender last made progress (a pass or a try)."
    )
    window_s: float = Field(
        description="A sender that made progress this many seconds ago or less counts as "
        "sending: the presence window and one try's timeouts (3 x NANONAV_WEBHOOK_TIMEOUT_S)."
    )


class Health(BaseModel):
    model_config = ConfigDict(
        json_schema_extra={
            "examples": [
                {
                    "status": "ok",
                    "database": True,
                    "revision": "0002",
                    "head": "0002",
                    "queue": {"queued": 3, "running": 2, "oldest_queued_at": "2026-11-30T04:00Z"},
                    "workers": {"seen": 2, "window_s": 30.0},
                    "webhooks": {
                        "due": 1,
                        "retrying": 0,
                        "oldest_due_at": "2026-11-30T04:00Z",
                        "overdue_s": 0.4,
                        "last_pass_at": "2026-11-30T04:00Z",
                        "window_s": 60.0,
                    },
                    "note": None,
                }
            ]
        }
    )

    status: Literal["ok", "unavailable"]
    database: bool = Field(description="Whether the database answered.")
    revision: str | None = Field(description="The database's migration revision.")
    head: str | None = Field(description="The newest migration this code knows.")
    queue: Queue | None = Field(None, description="The queue, when the database answered.")
    workers: Workers | None = Field(None, description="Workers seen, when the database answered.")
    webhooks: Webhooks | None = Field(
        None, description="Webhooks to send and their senders, when the database answered."
    )
    note: str | None = Field(
        None,
        description="Why queued jobs or due webhooks may not be moving, e.g. that no worker "
        "is running, or that none has sent webhooks lately (the status stays ok: jobs run).",
    )


class Version(BaseModel):
    model_config = ConfigDict(
        json_schema_extra={"examples": [{"name": "nanonav", "version": "0.1.0"}]}
    )

    name: str
    version: str
