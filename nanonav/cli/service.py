"""``nanonav api``, ``worker`` and ``migrate``: the parts of the job service.

The service and the worker are imported by name, when their subcommand runs: the nanonav
package never depends on them."""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING

from pydantic import ValidationError

from nanonav.cli.common import EXIT_OK, Failed, Subcommands, UsageError, settings_messages

if TYPE_CHECKING:
    from nanonav.settings import Settings


def _settings() -> Settings:
    from nanonav.settings import Settings

    try:
        return Settings()
    except ValidationError as error:
        raise UsageError(settings_messages(error)) from error


def add_api(subcommands: Subcommands) -> None:
    api = subcommands.add_parser(
        "api",
        help="serve the job service's REST API",
        description="Serve the REST API (uvicorn) over the database DATABASE_URL names "
        "(default ./var/nanonav.db). Run `nanonav migrate` first.",
    )
    api.add_argument("--host", help="bind address (default: $HOST or 127.0.0.1)")
    api.add_argument("--port", type=int, help="port (default: $PORT or 8000)")
    api.add_argument(
        "--processes",
        type=int,
        metavar="N",
        help="API processes sharing the port (default: $NANONAV_API_PROCESSES or 1)",
    )
    api.set_defaults(handler=_api)


def _api(args: argparse.Namespace) -> int:
    import importlib

    settings = _settings()
    port = settings.port if args.port is None else args.port
    if not 1 <= port <= 65535:
        raise UsageError([f"--port must be between 1 and 65535, not {port}"])
    processes = settings.api_processes if args.processes is None else args.processes
    if not 1 <= processes <= 64:
        raise UsageError([f"--processes must be between 1 and 64, not {processes}"])
    host = args.host or settings.host
    # served as every other way of starting the API is: the limits on connections, on slow
    # clients and the shutdown grace come with it
    server = importlib.import_module("service.server")
    connections = importlib.import_module("service.connections")
    try:
        server.run(settings, host=host, port=port, processes=processes)
    except connections.OpenFilesTooFew as error:
        raise UsageError([str(error)]) from error
    return EXIT_OK


def add_worker(subcommands: Subcommands) -> None:
    worker = subcommands.add_parser(
        "worker",
        help="run queued jobs",
        description="Claim jobs from the database DATABASE_URL names and run them until "
        "SIGTERM or Ctrl-C, which give the running job back to the queue.",
    )
    worker.add_argument(
        "--concurrency",
        type=int,
        metavar="N",
        help="worker processes (default: $NANONAV_WORKER_CONCURRENCY or 1)",
    )
    worker.add_argument(
        "--train",
        action="store_true",
        help="also claim the jobs that train a network (robots.policy ppo, recurrent_ppo); "
        "needs the rl extra (default: $NANONAV_WORKER_TRAINS)",
    )
    worker.set_defaults(handler=_worker)


def _worker(args: argparse.Namespace) -> int:
    import importlib

    settings = _settings()
    concurrency = settings.worker_concurrency if args.concurrency is None else args.concurrency
    if concurrency < 1:
        raise UsageError([f"--concurrency must be at least 1, not {concurrency}"])
    argv = ["--concurrency", str(concurrency), *(["--train"] if args.train else [])]
    importlib.import_module("worker.__main__").main(argv)
    return EXIT_OK


def add_migrate(subcommands: Subcommands) -> None:
    migrate = subcommands.add_parser(
        "migrate",
        help="bring the database's schema to the newest migration",
        description="Apply the Alembic migrations to the database DATABASE_URL names "
        "(default ./var/nanonav.db, created if missing).",
    )
    migrate.set_defaults(handler=_migrate)


def _migrate(args: argparse.Namespace) -> int:
    from sqlalchemy.engine import make_url
    from sqlalchemy.exc import SQLAlchemyError

    from nanonav.store.faults import reason
    from nanonav.store.migrate import head_revision, upgrade

    settings = _settings()
    shown = make_url(settings.database_url).render_as_string(hide_password=True)
    try:
        upgrade(settings.database_url)
    except SQLAlchemyError as error:
        raise Failed([f"cannot migrate {shown}: {reason(error)}"]) from error
    print(f"{shown} is at migration {head_revision()}")
    return EXIT_OK
