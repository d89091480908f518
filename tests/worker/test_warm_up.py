"""A worker makes every path a job can take ready before it claims one: after its warm-up, a
job of any preset, either physics or schedule, learning or evaluating a table, or evaluating
a network by action number or by a turn, needs no compiled function for types it has not
made ready (it would be compiled, or loaded, while the job holds its lease)."""

from __future__ import annotations

import subprocess
import sys

import pytest

pytestmark = pytest.mark.timeout(600)
JOBS = """
import sys

import numpy as np
from numba.core.dispatcher import Dispatcher

from nanonav.engine import simulate
from nanonav.rl.evaluate import evaluate
from nanonav.scenario import PRESETS, Scenario
from worker.loop import warm_up


# each compiled function of NanoNav's, and the signatures it is compiled (or loaded) for
def overloads():
    return {
        f"{module.__name__}.{name}": set(value.overloads)
        for module in list(sys.modules.values())
        if getattr(module, "__name__", "").startswith("nanonav.")
        for name, value in vars(module).items()
        if isinstance(value, Dispatcher)
    }


warm_up()
ready = overloads()
for name in PRESETS:
    preset = Scenario.model_validate({"preset": name})
    brownian = preset.physics.model == "active_brownian"
    # long enough for the longest decision interval a preset sets (0.1 s)
    short = {"physics": {"time_limit_s": 0.2}} if brownian else {}
    steps = {} if brownian else {"max_steps": 5}
    for schedule in ("sequential", "simultaneous"):
        data = {"preset": name, **short, "evaluation": {"worlds": 1},
                "robots": {"count": min(preset.robots.count, 20), "schedule": schedule}}
        scenario = Scenario.model_validate({**data, "learning": {"episodes": 1, **steps}})
        result = simulate(scenario)
        evaluated = Scenario.model_validate({**data, "learning": {"episodes": 0, **steps}})
        evaluate(evaluated, lambda rows: np.zeros(rows.shape[0], np.int64))
        if brownian:
            evaluate(evaluated, lambda rows: np.zeros((rows.shape[0], 2)), steering="continuous")
        if result.qtable is not None:
            simulate(evaluated, policy=result.qtable.values)
after = overloads()
new = sorted(name for name, signatures in after.items() if signatures - ready.get(name, set()))
print(len(new), new)
"""


def test_after_the_warm_up_no_job_compiles_anything() -> None:
    done = subprocess.run([sys.executable, "-c", JOBS], capture_output=True, text=True,
                          timeout=580, check=False)  # fmt: skip
    assert done.returncode == 0, done.stderr[-3000:]
    count, _, names = done.stdout.strip().partition(" ")
    assert count == "0", names
