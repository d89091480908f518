"""The simulation engine: fields, world, policies, Q-learning, metrics.

It knows nothing of HTTP or SQL: a scenario goes in, plain arrays and dicts come out.

Its public names are imported when first asked for (PEP 562), so that a process that reads
only the engine's plain data (``labels``, ``qlearning``'s tables of states, ``metrics``'
ranges) never loads numba and the compiled kernel: the API does not, until it draws. A module
that compiles imports ``compiled`` first, which points numba's cache at the engine's folder.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from nanonav.lazy import names_from

if TYPE_CHECKING:
    from nanonav.engine.fields import field_and_gradient as field_and_gradient
    from nanonav.engine.result import QTable as QTable
    from nanonav.engine.result import SimulationResult as SimulationResult
    from nanonav.engine.result import Trajectory as Trajectory
    from nanonav.engine.result import without_timings as without_timings
    from nanonav.engine.simulation import Progress as Progress
    from nanonav.engine.simulation import ProgressCallback as ProgressCallback
    from nanonav.engine.simulation import compiled_here as compiled_here
    from nanonav.engine.simulation import simulate as simulate

# where each public name lives
_HOMES = {
    "Progress": "simulation",
    "ProgressCallback": "simulation",
    "QTable": "result",
    "SimulationResult": "result",
    "Trajectory": "result",
    "compiled_here": "simulation",
    "field_and_gradient": "fields",
    "simulate": "simulation",
    "without_timings": "result",
}
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


# imported when first asked for: the package loads none of its modules itself
__getattr__ = names_from(__name__, _HOMES, globals())
