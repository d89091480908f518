"""Compile the engine's two large kernels into numba's on-disk cache before the tests start.

Each compiles for a minute or so from a cold cache (``benchmarks/first_start.py``):
``simulate``'s episode loop, and the world step that every environment drives from outside
(``Worlds.step``). Left to the tests, every test process compiles the first for itself and one
of them the second, while the other waits or works alone. Compiled here side by side, one
process each, the test processes then load both from the cache. Neither part needs more than
NanoNav's own dependencies, so that ``make test`` compiles them while pip installs the test
tools and the checks run, on the core those leave idle. Then a worker's preparation
(``worker.loop.prepare``) makes the cache ready for the workers the tests start.

    python -m tests.compile_ahead                     # every part
    python -m tests.compile_ahead kernel|env|worker   # one part, in this process
"""

from __future__ import annotations

import subprocess
import sys
import time

# Two rounds: the kernels side by side, then a worker's preparation, which loads them and
# compiles what else a job can take (a network's evaluation) once, and says the cache is ready
# for workers; left to the tests, the first workers to start prepared it at once, three over.
ROUNDS = (("kernel", "env"), ("worker",))
PARTS = tuple(part for parts in ROUNDS for part in parts)
SMALL = {"preset": "paper-single", "learning": {"episodes": 1, "max_steps": 5},
         "evaluation": {"worlds": 1}}  # fmt: skip


def compile_part(part: str) -> None:
    """Run the smallest work that compiles ``part``'s kernel (or loads it from the cache)."""
    if part == "kernel":
        from nanonav.engine import simulate
        from nanonav.scenario import Scenario

        simulate(Scenario.model_validate(SMALL))
    elif part == "env":
        import numpy as np

        from nanonav.engine.worlds import Worlds
        from nanonav.scenario import Scenario

        # as NanoNavEnv's reset and step call it (gymnasium is not needed to compile it)
        worlds = Worlds(Scenario.model_validate(SMALL), 1, "simultaneous")
        worlds.step(None, np.ones(1, dtype=np.bool_))
        worlds.step(worlds.blank_actions(), np.zeros(1, dtype=np.bool_), checked=True)
    elif part == "worker":
        import threading

        from worker.loop import prepare

        if not prepare(threading.Event()):
            raise RuntimeError("the worker's preparation stopped")
    else:
        raise ValueError(f"no part {part!r}: one of {', '.join(PARTS)}")


def compile_all(timeout_s: float = 1200.0) -> list[str]:
    """Compile every part, each in a process of its own, a round's parts at once; returns a
    line per part (how long it took, or how it failed: the tests that use it will then fail,
    or compile it, in their own words)."""
    started = time.perf_counter()
    lines = []
    for parts in ROUNDS:
        running = {
            part: subprocess.Popen(
                [sys.executable, "-m", "tests.compile_ahead", part],
                stdout=subprocess.DEVNULL,
                stderr=subprocess.PIPE,
                text=True,
            )
            for part in parts
        }
        for part, process in running.items():
            try:
                _, err = process.communicate(
                    timeout=max(1.0, timeout_s - (time.perf_counter() - started))
                )
            except subprocess.TimeoutExpired:
                process.kill()
                process.communicate()
                lines.append(f"{part}: not compiled within {timeout_s:.0f} s")
                continue
            took = time.perf_counter() - started
            if process.returncode == 0:
                lines.append(f"{part}: ready after {took:.0f} s")
            else:
                last = err.strip().splitlines()[-1:] or ["(no output)"]
                lines.append(f"{part}: failed ({last[0]})")
    return lines


if __name__ == "__main__":
    if len(sys.argv) > 1:
        compile_part(sys.argv[1])
    else:  # a part that fails says so and leaves it to the tests: never a failure here
        for line in compile_all():
            print(f"compiled ahead: {line}")
