"""Where a world-step of the vector env goes, in ns, from the step alone to the env, on one
core: one world stepped over and over in one compiled loop; every world of the batch in turn
so; ``Worlds.step``, the compiled call from Python that steps every world; the vector env's
``step``; beside ``simulate``'s own loop, which also learns (``env.py``'s figure
for one robot).

    python benchmarks/env_breakdown.py           # about 6 min the first time (it compiles
                                                 # its own loop), then about 30 s
    python benchmarks/env_breakdown.py --quick   # a smoke run

Worlds are 'paper-single' (one robot each), random actions; figures are medians of 3 repeats.
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

sys.path.insert(0, str(Path(__file__).resolve().parent))

from env import SINGLE, engine_rate, median_rate, vector_env

from nanonav.engine.compiled import uncounted
from nanonav.engine.generators import generator_at, handle
from nanonav.engine.phases import CLOCK_OVER, Sim
from nanonav.engine.state import KernelParams
from nanonav.engine.stepping import reset_world, sim_at, step_world
from nanonav.engine.world import DYNAMICS_STREAM, EVALUATION_STREAM, stream
from nanonav.engine.worlds import Worlds
from nanonav.scenario import Scenario

WORLDS = 1000


@uncounted
def _in_turn(
    p: KernelParams, world_handles: NDArray[np.uint64], handles: NDArray[np.uint64], batch: Sim,
    steps: int, worlds: int, actions: NDArray[np.int64], turns: NDArray[np.float64],
    directions: NDArray[np.float64],
) -> None:  # fmt: skip
    """``steps`` world-steps of the batch's first ``worlds`` worlds in turn in one compiled
    loop, each world on its own generators, a fresh world drawn where one is over: the vector
    env's step without its compiled call."""
    for j in range(steps):
        k = j % worlds
        sim = sim_at(batch, k)
        if sim.pc.clock[CLOCK_OVER]:
            reset_world(p, generator_at(world_handles, k), generator_at(handles, k), sim)
        step_world(p, generator_at(handles, k), sim, actions[j & 1023], turns[k], directions)


def rows(worlds: int, robot_steps: int) -> list[tuple[str, float]]:
    """(what, robot-steps/s) from the step alone to the env, and ``simulate`` beside them."""
    batch = Worlds(Scenario.model_validate(SINGLE), worlds, "simultaneous")
    batch.step(None, np.ones(worlds, dtype=np.bool_))  # compiles, or loads the cache
    actions = np.random.default_rng(0).integers(0, batch.actions, (1024, 1))
    drawn = np.random.default_rng(1).integers(0, batch.actions, (64, worlds, 1))
    # the generators are kept here while the loop draws from their handles
    world_rngs = [stream(k, EVALUATION_STREAM) for k in range(worlds)]
    rngs = [stream(k, DYNAMICS_STREAM) for k in range(worlds)]
    world_handles = np.stack([handle(g) for g in world_rngs])
    handles = np.stack([handle(g) for g in rngs])
    turns = np.zeros((worlds, 1, 2))

    def in_turn(count: int) -> Callable[[], tuple[int, float]]:
        def run() -> tuple[int, float]:
            started = time.perf_counter()
            _in_turn(batch.params, world_handles, handles, batch.batch, robot_steps, count,
                     actions, turns, batch.directions)  # fmt: skip
            return robot_steps, time.perf_counter() - started

        return run

    def stepped() -> tuple[int, float]:
        calls = max(1, robot_steps // worlds)
        started = time.perf_counter()
        for j in range(calls):
            batch.step(drawn[j & 63], batch.over, checked=True)
        return calls * worlds, time.perf_counter() - started

    in_turn(1)()  # compiled (or loaded) before any timing
    return [
        ("one world over and over, one compiled loop", median_rate(in_turn(1))),
        (f"{worlds:,} worlds in turn, one compiled loop", median_rate(in_turn(worlds))),
        (f"Worlds.step, {worlds:,} worlds a call", median_rate(stepped)),
        (f"NanoNavVectorEnv.step, {worlds:,} worlds", median_rate(vector_env(worlds, robot_steps))),
        ("simulate, one robot (it also learns)", engine_rate(SINGLE, robot_steps // 4)),
    ]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="small workloads")
    args = parser.parse_args(argv)
    scale = 10 if args.quick else 1
    print("where a world-step of the vector env goes (paper-single, one robot a world)")
    for label, rate in rows(WORLDS // scale, 2_000_000 // scale):
        print(f"  {label:48s} {1e9 / rate:7.0f} ns  {rate:>12,.0f} robot-steps/s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
