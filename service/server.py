"""How the API is served, however it is started: ``nanonav api`` (and so ``make run``), the
tests' processes and in-thread servers. One uvicorn configuration for all of them, so that the
limits of :mod:`service.connections` and the shutdown grace apply to each."""

from __future__ import annotations

import contextlib
import sys
from typing import Any

import uvicorn
from uvicorn.config import STARTUP_FAILURE
from uvicorn.supervisors import Multiprocess

from nanonav.settings import Settings
from service.connections import BoundedConfig, ConnectionLimits, fit_open_files

APP = "service.app:create_app"
# Seconds a process of several may take to answer its supervisor's health check before it is
# killed and started again: uvicorn's 5 s killed processes still starting (importing the
# engine) on a loaded machine, one after another, for minutes
PROCESS_HEALTHCHECK_S = 60.0


def server_config(app: Any, settings: Settings, **options: Any) -> BoundedConfig:
    """uvicorn's configuration for ``app`` (an ASGI app, or an import string) under the limits
    ``settings`` set; ``options`` are uvicorn's own (host, port, workers, log_level...).
    Raises :class:`service.connections.OpenFilesTooFew` if the limits do not fit the process's
    open files."""
    limits = ConnectionLimits.of(settings)
    fit_open_files(limits)
    options.setdefault("timeout_graceful_shutdown", settings.shutdown_grace_s)
    options.setdefault("timeout_worker_healthcheck", PROCESS_HEALTHCHECK_S)
    return BoundedConfig(app, limits=limits, **options)


def run(settings: Settings, *, host: str, port: int, processes: int) -> None:
    """Serve the API on ``host:port`` from ``processes`` processes sharing the socket, until a
    signal stops it (what ``uvicorn.run`` does, with this module's configuration)."""
    config = server_config(APP, settings, factory=True, host=host, port=port, workers=processes)
    server = uvicorn.Server(config)
    with contextlib.suppress(KeyboardInterrupt):
        if config.workers > 1:
            Multiprocess(config, sockets=[config.bind_socket()]).run()
        else:
            server.run()
    if config.workers == 1 and not server.started:
        sys.exit(STARTUP_FAILURE)
