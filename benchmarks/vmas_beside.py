"""NanoNav's vector env beside VMAS's vectorised ``navigation``, in one run, one core each.

VMAS (Bettini et al., 2022) is the vectorised multi-agent simulator of the field: PyTorch
tensors of worlds x agents, stepped in one call, as NanoNav's ``NanoNavVectorEnv`` steps worlds
in one compiled call. Both are stepped here as a new user steps them, from a Python loop with
random actions drawn each step, 1,000 worlds a call, and counted in agent-steps (robot-steps)
per second:

- NanoNav: ``paper-single`` (the lattice, one robot and ten obstacles a world), and
  ``tumour-microswimmers`` with one robot deciding every step (active Brownian, 40 obstacles,
  the Berg-Purcell sensor); a finished world is drawn afresh within the call.
- VMAS 1.5: ``navigation`` with one agent and with four (its default), continuous actions, on
  the CPU, with ``torch.set_num_threads(1)``; its worlds do not end on their own (no
  ``max_steps``), so none is reset, which favours it slightly.

VMAS is not a NanoNav dependency (it pulls the old ``gym`` and ``pyglet``): install it to run
this, ``pip install vmas``; without it only NanoNav's figures are printed.

    python benchmarks/vmas_beside.py            # about a minute
    python benchmarks/vmas_beside.py --quick
"""

from __future__ import annotations

import argparse
import importlib.util
import sys
import time
from collections.abc import Callable
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from env import median_rate, vector_env

WORLDS = 1000
LATTICE = {"preset": "paper-single"}
# every step a decision, as VMAS's agents act every step (the preset's robots hold a decision
# for a second, 100 steps: an env step then is 100 robot-steps)
BROWNIAN = {
    "preset": "tumour-microswimmers",
    "robots": {"count": 1},
    "learning": {"decision_interval_s": 0.01},
    "physics": {"dt_s": 0.01},
}


def nanonav_run(scenario: dict[str, object], calls: int) -> Callable[[], tuple[int, float]]:
    """The vector env over ``WORLDS`` worlds of ``scenario``, compiled (or loaded from numba's
    cache) before it is timed."""
    vector_env(2, 2, scenario)()
    return vector_env(WORLDS, calls * WORLDS, scenario)


def vmas_run(agents: int, calls: int) -> Callable[[], tuple[int, float]]:
    import torch
    import vmas

    torch.set_num_threads(1)
    env = vmas.make_env(
        "navigation", num_envs=WORLDS, device="cpu", continuous_actions=True, seed=0,
        n_agents=agents,
    )  # fmt: skip
    env.step(env.get_random_actions())

    def run() -> tuple[int, float]:
        env.reset()
        started = time.perf_counter()
        for _ in range(calls):
            env.step(env.get_random_actions())
        return calls * WORLDS * agents, time.perf_counter() - started

    return run


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer steps")
    args = parser.parse_args(argv)
    calls = 100 if args.quick else 1000
    rows = [
        ("NanoNav vector env, paper-single (lattice), 1 robot", nanonav_run(LATTICE, calls)),
        ("NanoNav vector env, tumour-microswimmers, 1 robot", nanonav_run(BROWNIAN, calls)),
    ]
    have_vmas = importlib.util.find_spec("vmas") is not None
    if have_vmas:
        for agents in (1, 4):
            rows.append((f"VMAS navigation, {agents} agent(s)", vmas_run(agents, calls // 5)))
    print(f"{WORLDS:,} worlds a call, random actions, one core; agent-steps per second")
    rates = {}
    for label, run in rows:
        rates[label] = median_rate(run)
        print(f"  {label:55s} {rates[label]:>12,.0f}")
    if not have_vmas:
        print("VMAS is not installed (pip install vmas): its rows are missing")
        return 0
    theirs = rates["VMAS navigation, 1 agent(s)"]
    for label, _ in rows[:2]:
        ours = rates[label]
        status = "meets" if ours >= theirs else "BELOW"
        print(f"{status} target: {label}, {ours:,.0f}, against VMAS's navigation at one agent, "
              f"{theirs:,.0f} (x{ours / theirs:.2f})")  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
