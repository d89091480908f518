"""Small runs of the swarm (robots that take up space, cells that are treated, signals), drawn
by the treatment and trajectory tests."""

from typing import Any

from nanonav.engine import SimulationResult, simulate
from nanonav.scenario import preset_scenario


def swarm_run(**overrides: Any) -> SimulationResult:
    """The diffuse-tumour preset in one evaluation world, with ``overrides``."""
    fields: dict[str, Any] = {"seed": 0, "evaluation": {"worlds": 1}, **overrides}
    return simulate(preset_scenario("diffuse-tumour", **fields))


def treating_run() -> SimulationResult:
    """Three cells that one payload each treats, an attractant, long enough to treat them all."""
    return swarm_run(
        cells={"count": 3, "capacity": 1},
        communication={"model": "attractant"},
        learning={"max_steps": 600},
    )


def untreated_run() -> SimulationResult:
    """The same swarm stopped after so few steps that no robot reaches a cell."""
    return swarm_run(
        cells={"count": 3, "capacity": 1},
        communication={"model": "attractant"},
        learning={"max_steps": 5},
    )
