"""The ``nanonav`` command.

Each subcommand is one ``add_<name>`` function that declares its arguments and sets ``handler``
to the function that runs it: ``run`` in ``run.py`` runs a scenario here; ``api``, ``worker`` and
``migrate`` in ``service.py`` run the job service; ``submit``, ``study``, ``fetch``, ``jobs`` and
``delete`` in ``remote.py``, and ``policy`` and ``policies`` in ``policies.py``, talk to a running
API; ``train`` in ``train.py`` trains a deep learner here. ``main`` parses, dispatches and
turns the errors a user can cause into a message on stderr and an exit code. Adding a
subcommand means adding one such function and one line in ``build_parser``.
"""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Callable

import nanonav
from nanonav.cli import policies, remote, run, service, train
from nanonav.cli.common import (
    EXIT_FAILED,
    EXIT_INTERRUPTED,
    EXIT_PIPE_CLOSED,
    EXIT_USAGE,
    Failed,
    UsageError,
)
from nanonav.client import ApiError

__all__ = ["Failed", "UsageError", "build_parser", "main"]

Handler = Callable[[argparse.Namespace], int]


def build_parser() -> argparse.ArgumentParser:
    """The whole command line: one subparser per subcommand."""
    parser = argparse.ArgumentParser(
        prog="nanonav",
        description="Simulations of learning nanorobots that hunt cancer cells in 3-D tissue.",
        epilog="Exit codes: 0 done; 1 the work failed, or the server failed or could not be "
        "reached; 2 input to fix (here, or as the server judged it); 130 interrupted; 141 "
        "the output's reader left early (as `| head` does).",
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {nanonav.__version__}")
    subcommands = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    run.add_run(subcommands)
    service.add_api(subcommands)
    service.add_worker(subcommands)
    service.add_migrate(subcommands)
    remote.add_submit(subcommands)
    remote.add_study(subcommands)
    remote.add_fetch(subcommands)
    remote.add_jobs(subcommands)
    remote.add_delete(subcommands)
    policies.add_policy(subcommands)
    policies.add_policies(subcommands)
    train.add_train(subcommands)
    for subparser in subcommands.choices.values():
        # so that an argument it does not know is said with its usage (``main``)
        subparser.set_defaults(parser=subparser)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Run the command; returns the exit code instead of exiting, so tests can call it.

    Exit codes: 0 done; 1 the work failed, or the server failed or could not be reached; 2 input
    to fix (here, or a 4xx answer of the server); 130 interrupted; 141 the reader of the output
    left early."""
    parser = build_parser()
    try:
        args, unknown = parser.parse_known_args(argv)
        if unknown:
            # said with the subcommand's usage, not the top level's (which lists commands)
            args.parser.error(f"unrecognized arguments: {' '.join(unknown)}")
    except SystemExit as stop:
        return stop.code if isinstance(stop.code, int) else EXIT_USAGE
    handler: Handler = args.handler

    def say(lines: list[str]) -> None:
        for line in lines:
            print(f"nanonav {args.command}: {line}", file=sys.stderr)

    try:
        return handler(args)
    except UsageError as error:
        say(error.lines)
        return EXIT_USAGE
    except Failed as error:
        say(error.lines)
        return EXIT_FAILED
    except ApiError as error:
        say(str(error).splitlines())
        return EXIT_USAGE if 400 <= error.status < 500 else EXIT_FAILED
    except KeyboardInterrupt as stop:
        say([str(stop) or "interrupted"])
        return EXIT_INTERRUPTED
    except BrokenPipeError:
        # The reader left (`nanonav study --id 2 | head -5`): stop quietly, as cat does, and
        # point stdout at nothing so the interpreter's last flush raises no second error.
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        return EXIT_PIPE_CLOSED
