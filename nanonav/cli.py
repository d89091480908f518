"""The ``nanonav`` command.

Each subcommand is one ``_add_<name>`` function that declares its arguments and sets ``handler``
to the function that runs it; ``main`` parses, dispatches and turns the errors a user can cause
into a message on stderr and an exit code. Adding a subcommand means adding one such pair and
one line in ``build_parser``.
"""

from __future__ import annotations

import argparse
import json
import signal
import sys
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from types import FrameType
from typing import TYPE_CHECKING, Any

import numpy as np
from pydantic import ValidationError

from nanonav.engine import Progress, SimulationResult, simulate
from nanonav.scenario import PRESETS, Scenario, ScenarioError

if TYPE_CHECKING:
    from nanonav.settings import Settings

EXIT_OK = 0
EXIT_USAGE = 2
EXIT_INTERRUPTED = 130
MAX_ROBOT_ROWS = 20

Handler = Callable[[argparse.Namespace], int]


class UsageError(Exception):
    """Input the user can fix: one message per line, printed to stderr with exit code 2."""

    def __init__(self, lines: list[str]) -> None:
        super().__init__("\n".join(lines))
        self.lines = lines


def build_parser() -> argparse.ArgumentParser:
    """The whole command line: one subparser per subcommand."""
    parser = argparse.ArgumentParser(
        prog="nanonav",
        description="Simulations of learning nanorobots that hunt cancer cells in 3-D tissue.",
    )
    subcommands = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    _add_run(subcommands)
    _add_api(subcommands)
    _add_worker(subcommands)
    _add_migrate(subcommands)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Run the command; returns the exit code instead of exiting, so tests can call it."""
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as stop:
        return stop.code if isinstance(stop.code, int) else EXIT_USAGE
    handler: Handler = args.handler
    try:
        return handler(args)
    except UsageError as error:
        for line in error.lines:
            print(f"nanonav {args.command}: {line}", file=sys.stderr)
        return EXIT_USAGE
    except KeyboardInterrupt:
        print(f"nanonav {args.command}: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED


# ---------------------------------------------------------------- run


def _add_run(subcommands: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    run = subcommands.add_parser(
        "run",
        help="run one simulation and print the paper's Table 1",
        description="Run one simulation in this process and print its metrics (paper Table 1). "
        "The scenario is read from --scenario, then --preset and --seed override it.",
    )
    run.add_argument(
        "--preset",
        choices=sorted(PRESETS),
        help="base values (explicit fields of the scenario file override them)",
    )
    run.add_argument("--scenario", type=Path, metavar="FILE.json", help="scenario as a JSON object")
    run.add_argument("--seed", type=int, metavar="N", help="seed of every random draw")
    run.add_argument(
        "--out",
        type=Path,
        metavar="DIR",
        help="write the pictures (<name>.png), result.npz and metrics.json here",
    )
    run.add_argument(
        "--json",
        action="store_true",
        help="print only the metrics document as one JSON object on stdout",
    )
    run.set_defaults(handler=_run)


def _run(args: argparse.Namespace) -> int:
    scenario = load_scenario(args.scenario, preset=args.preset, seed=args.seed)
    show_bar = not args.json and sys.stderr.isatty()
    with _stop_on_interrupt() as stopped, _progress_bar(show_bar) as report:

        def progress(state: Progress) -> bool:
            report(state)
            return not stopped()

        try:
            result = simulate(scenario, progress)
        except ScenarioError as error:
            raise UsageError([str(error)]) from error
    if not result.completed:
        raise KeyboardInterrupt
    document = result.to_dict()
    written = _write_outputs(result, document, args.out) if args.out is not None else []
    if args.json:
        print(json.dumps(document))
    else:
        print(format_table(result))
        if written:
            print(f"\nWrote {len(written)} files to {args.out}")
    return EXIT_OK


def load_scenario(path: Path | None, *, preset: str | None, seed: int | None) -> Scenario:
    """The scenario from a JSON file (or the defaults), with ``preset`` and ``seed`` on top."""
    data: dict[str, Any] = {}
    if path is not None:
        try:
            text = path.read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError) as error:
            raise UsageError([f"cannot read {path}: {error}"]) from error
        try:
            loaded = json.loads(text)
        except json.JSONDecodeError as error:
            raise UsageError(
                [f"{path}: invalid JSON at line {error.lineno} column {error.colno}: {error.msg}"]
            ) from error
        if not isinstance(loaded, dict):
            raise UsageError([f"{path}: the scenario must be a JSON object"])
        data = loaded
    if preset is not None:
        data["preset"] = preset
    if seed is not None:
        data["seed"] = seed
    try:
        return Scenario.model_validate(data)
    except ValidationError as error:
        raise UsageError(validation_messages(error)) from error


def validation_messages(error: ValidationError) -> list[str]:
    """One line per error, naming the field by its dotted path (``robots.count: ...``)."""
    lines = []
    for item in error.errors(include_url=False):
        where = ".".join(str(part) for part in item["loc"]) or "scenario"
        lines.append(f"{where}: {item['msg']}")
    return lines


@contextmanager
def _stop_on_interrupt() -> Iterator[Callable[[], bool]]:
    """The first Ctrl-C asks the simulation to stop at its next progress report (it cannot be
    interrupted inside a compiled kernel); a second one interrupts at once."""
    hits: list[int] = []

    def on_sigint(signum: int, frame: FrameType | None) -> None:
        hits.append(signum)
        if len(hits) > 1:
            raise KeyboardInterrupt

    try:
        previous = signal.signal(signal.SIGINT, on_sigint)
    except ValueError:  # not the main thread: leave signals alone
        yield lambda: False
        return
    try:
        yield lambda: bool(hits)
    finally:
        signal.signal(signal.SIGINT, previous)


@contextmanager
def _progress_bar(enabled: bool) -> Iterator[Callable[[Progress], None]]:
    if not enabled:
        yield lambda state: None
        return
    from tqdm import tqdm

    bar = tqdm(
        total=1.0, file=sys.stderr, bar_format="{percentage:3.0f}%|{bar}| {desc} [{elapsed}]"
    )

    def report(state: Progress) -> None:
        bar.n = round(state.fraction, 4)
        bar.set_description_str(
            f"episode {min(state.episode + 1, state.episodes)}/{state.episodes}, "
            f"step {state.step}/{state.max_steps}",
            refresh=True,
        )

    try:
        yield report
    finally:
        bar.close()


def _write_outputs(result: SimulationResult, document: dict[str, Any], out: Path) -> list[Path]:
    from nanonav.plots import render_all

    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as error:
        raise UsageError([f"cannot create {out}: {error}"]) from error
    written = []
    for name, png in render_all(result).items():
        written.append(out / f"{name}.png")
        written[-1].write_bytes(png)
    written.append(out / "result.npz")
    np.savez_compressed(written[-1], **result.arrays())  # type: ignore[arg-type]
    written.append(out / "metrics.json")
    written[-1].write_text(json.dumps(document, indent=2) + "\n", encoding="utf-8")
    return written


# ---------------------------------------------------------------- the job service
# The service and the worker are imported by name, when their subcommand runs: the nanonav
# package never depends on them.


def _settings() -> Settings:
    from nanonav.settings import Settings

    try:
        return Settings()
    except ValidationError as error:
        raise UsageError(validation_messages(error)) from error


def _add_api(subcommands: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    api = subcommands.add_parser(
        "api",
        help="serve the job service's REST API",
        description="Serve the REST API (uvicorn) over the database DATABASE_URL names "
        "(default ./var/nanonav.db). Run `nanonav migrate` first.",
    )
    api.add_argument("--host", help="bind address (default: $HOST or 127.0.0.1)")
    api.add_argument("--port", type=int, help="port (default: $PORT or 8000)")
    api.set_defaults(handler=_api)


def _api(args: argparse.Namespace) -> int:
    import uvicorn

    settings = _settings()
    port = settings.port if args.port is None else args.port
    if not 1 <= port <= 65535:
        raise UsageError([f"--port must be between 1 and 65535, not {port}"])
    host = args.host or settings.host
    uvicorn.run("service.app:create_app", factory=True, host=host, port=port)
    return EXIT_OK


def _add_worker(subcommands: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
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
    worker.set_defaults(handler=_worker)


def _worker(args: argparse.Namespace) -> int:
    import importlib

    settings = _settings()
    concurrency = settings.worker_concurrency if args.concurrency is None else args.concurrency
    if concurrency < 1:
        raise UsageError([f"--concurrency must be at least 1, not {concurrency}"])
    importlib.import_module("worker.__main__").main(["--concurrency", str(concurrency)])
    return EXIT_OK


def _add_migrate(subcommands: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    migrate = subcommands.add_parser(
        "migrate",
        help="bring the database's schema to the newest migration",
        description="Apply the Alembic migrations to the database DATABASE_URL names "
        "(default ./var/nanonav.db, created if missing).",
    )
    migrate.set_defaults(handler=_migrate)


def _migrate(args: argparse.Namespace) -> int:
    from sqlalchemy.engine import make_url

    from nanonav.store.migrate import head_revision, upgrade

    settings = _settings()
    upgrade(settings.database_url)
    shown = make_url(settings.database_url).render_as_string(hide_password=True)
    print(f"{shown} is at migration {head_revision()}")
    return EXIT_OK


# ---------------------------------------------------------------- Table 1


def _number(value: Any, digits: int = 2, suffix: str = "") -> str:
    if value is None:
        return "n/a"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, int):
        return f"{value}{suffix}"
    return f"{float(value):.{digits}f}{suffix}"


def _seconds(value: Any) -> str:
    if value is None:
        return "n/a"
    seconds = float(value)
    return f"{seconds:.2f} seconds" if seconds >= 1 else f"{seconds:.3g} seconds"


def _percent(value: Any) -> str:
    return "n/a" if value is None else f"{100 * float(value):.1f}%"


def format_table(result: SimulationResult) -> str:
    """Table 1 of the paper as text, with success rate, collisions and path efficiency, and for a
    swarm a per-robot table (the first ``MAX_ROBOT_ROWS`` robots)."""
    scenario = result.scenario
    summary = result.summary
    rows = [
        ("Total Steps", _number(summary.get("total_steps"))),
        ("Final Distance", _number(summary.get("final_distance"))),
        ("Average Distance", _number(summary.get("average_distance"))),
        ("Average Biomarker Concentration", _number(summary.get("average_concentration"))),
        ("Simulation Duration", _seconds(summary.get("duration_s"))),
        ("Success Rate", _percent(summary.get("success_rate"))),
        ("Collisions", _number(summary.get("collisions"))),
        ("Path Efficiency", _number(summary.get("path_efficiency"))),
    ]
    robots = scenario.robots.count
    header = (
        f"Table 1: {scenario.preset or 'custom scenario'}, seed {scenario.seed}, "
        f"{robots} robot{'s' if robots > 1 else ''}, {scenario.cells.count} "
        f"cell{'s' if scenario.cells.count > 1 else ''}, {scenario.robots.policy}, "
        f"{scenario.learning.episodes} training episodes + evaluation"
    )
    lines = [header, *_text_table(("Parameter", "Result"), rows, align_right=(False, True))]
    if robots > 1 and result.robots:
        lines += ["", "Per robot (evaluation episode):"]
        shown = result.robots[:MAX_ROBOT_ROWS]
        robot_rows = [
            (
                str(row.get("robot")),
                _number(row.get("reached")),
                _number(row.get("total_steps")),
                _number(row.get("final_distance")),
                _number(row.get("average_distance")),
                _number(row.get("average_concentration")),
                _number(row.get("collisions")),
                _number(row.get("path_efficiency")),
            )
            for row in shown
        ]
        columns = ("robot", "reached", "steps", "final dist", "avg dist", "avg conc",
                   "collisions", "path eff")  # fmt: skip
        lines += _text_table(columns, robot_rows, align_right=(True,) * len(columns))
        if len(result.robots) > len(shown):
            lines.append(
                f"... and {len(result.robots) - len(shown)} more robots (see --json or "
                "metrics.json)"
            )
    return "\n".join(lines)


def _text_table(
    columns: tuple[str, ...], rows: Sequence[tuple[str, ...]], *, align_right: tuple[bool, ...]
) -> list[str]:
    widths = [max(len(c), *(len(r[i]) for r in rows)) for i, c in enumerate(columns)]

    def line(cells: tuple[str, ...]) -> str:
        return "  ".join(
            cell.rjust(w) if right else cell.ljust(w)
            for cell, w, right in zip(cells, widths, align_right, strict=True)
        ).rstrip()

    rule = "  ".join("-" * w for w in widths)
    return [line(columns), rule, *(line(r) for r in rows)]


if __name__ == "__main__":
    sys.exit(main())
