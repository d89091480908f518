"""``nanonav run``: one simulation in this process, printed as the paper's Table 1.

The engine is imported when the subcommand runs, so that the commands that only talk to a
server start without loading numba."""

from __future__ import annotations

import argparse
import json
import signal
import sys
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from types import FrameType
from typing import TYPE_CHECKING, Any

from pydantic import ValidationError

from nanonav.cli.common import (
    EXIT_OK,
    Subcommands,
    UsageError,
    add_set_option,
    read_json_object,
    validation_messages,
    with_settings,
)
from nanonav.cli.tables import format_table, plural
from nanonav.scenario import PRESETS, Scenario, ScenarioError

if TYPE_CHECKING:
    from nanonav.engine import Progress, SimulationResult


def add_run(subcommands: Subcommands) -> None:
    run = subcommands.add_parser(
        "run",
        help="run one simulation here and print the paper's Table 1",
        description="Run one simulation in this process and print its metrics (paper Table 1). "
        "The scenario is read from --scenario, then --set, --preset and --seed override it.",
    )
    run.add_argument(
        "--preset",
        choices=sorted(PRESETS),
        help="base values (explicit fields of the scenario file override them)",
    )
    run.add_argument("--scenario", type=Path, metavar="FILE.json", help="scenario as a JSON object")
    run.add_argument("--seed", type=int, metavar="N", help="seed of every random draw")
    add_set_option(run, "the scenario file's")
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
    from nanonav.engine import compiled_here, simulate

    scenario = load_scenario(args.scenario, preset=args.preset, seed=args.seed,
                             settings=args.settings)  # fmt: skip
    source = scenario.policy_from
    if source is not None:
        named = f"{source} is a policy" if isinstance(source, str) else f"job {source} is a job"
        raise UsageError(
            [
                f"policy_from: {named} of the service, whose table only the service can read; "
                "submit this scenario with `nanonav submit`"
            ]
        )
    if not compiled_here():
        # the first run after an install or a change compiles the engine, silently otherwise
        print("nanonav run: compiling the engine for this machine, once: about a minute on two "
              "cores (later runs load it in seconds)", file=sys.stderr, flush=True)  # fmt: skip
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
        print(format_table(document))
        if written:
            print(f"\nWrote {plural(len(written), 'file')} to {args.out}")
    return EXIT_OK


def load_scenario(
    path: Path | None, *, preset: str | None, seed: int | None,
    settings: list[tuple[list[str], Any]] | None = None,
) -> Scenario:  # fmt: skip
    """The scenario from a JSON file (or the defaults), with ``--set``'s ``settings``, then
    ``preset`` and ``seed`` on top."""
    data = {} if path is None else read_json_object(path, "scenario")
    with_settings(data, settings or [])
    if preset is not None:
        data["preset"] = preset
    if seed is not None:
        data["seed"] = seed
    try:
        return Scenario.model_validate(data)
    except ValidationError as error:
        raise UsageError(validation_messages(error)) from error


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
    import numpy as np

    from nanonav.pictures.job import render_all

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
