"""``python -m worker.health``: exit 0 if a worker on this machine said it was alive within
the last 30 s (it says so every 5 s from a thread, from its start: one that prepares the engine
is alive), 1 otherwise: the worker container's health check. It proves the process runs and
reaches the store, which a process check alone does not."""

from __future__ import annotations

import socket
import sys

from sqlalchemy.exc import SQLAlchemyError

from nanonav.settings import Settings
from nanonav.store import JobStore
from nanonav.store.queue import PRESENCE_WINDOW_S


def healthy(settings: Settings, host: str | None = None) -> bool:
    """Whether a worker on ``host`` (this machine) was seen within the presence window, ready
    or preparing (restarted for being slow to compile, it would compile again)."""
    store = JobStore.from_url(settings.database_url, busy_timeout_s=5.0)
    try:
        census = store.census(seen_within_s=PRESENCE_WINDOW_S, host=host or socket.gethostname())
    except SQLAlchemyError:
        return False
    finally:
        store.close()
    return census.workers + census.preparing > 0


if __name__ == "__main__":
    sys.exit(0 if healthy(Settings()) else 1)
