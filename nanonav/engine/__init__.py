"""The simulation engine: fields, world, policies, Q-learning, metrics.

It knows nothing of HTTP or SQL: a scenario goes in, plain arrays and dicts come out.
"""

# first: numba's cache is pointed at the folder of this engine's digest before anything of
# the engine is compiled or loaded (``compiled.keep_compiled_code``)
from nanonav.engine import compiled  # noqa: F401  # isort: skip
from nanonav.engine.fields import field_and_gradient
from nanonav.engine.result import QTable, SimulationResult, Trajectory, without_timings
from nanonav.engine.simulate import Progress, ProgressCallback, compiled_here, simulate

__all__ = [
    "Progress",
    "ProgressCallback",
    "QTable",
    "SimulationResult",
    "Trajectory",
    "compiled_here",
    "field_and_gradient",
    "simulate",
    "without_timings",
]
