"""A job's evaluation episode as extended XYZ, which OVITO, ParaView (its XYZ reader), VMD and
ASE open: one frame per recorded step, the robots, the cells and the obstacles of the first
evaluation world as particles, in the physics' own units.

Each particle's ``species`` is a chemical symbol, as the format's readers want one: ``N`` a
nanorobot, ``C`` a cancer cell, ``O`` an obstacle; ``kind`` says it in words and ``radius`` is
its size (0 for the lattice's point cells). Each frame's comment line gives the box
(``Lattice`` and ``Origin``: the cube the world lives in, centred on 0), ``pbc="F F F"`` (walls,
not periodic), and ``step``, ``time`` with ``time_unit`` (seconds in the active Brownian
physics, steps in the lattice) and ``length_unit`` (µm written ``um``, or the lattice's
``lattice`` units).
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from typing import Any

import numpy as np
from numpy.typing import NDArray

from nanonav.scenario import Scenario

ROBOT, CELL, OBSTACLE = "N", "C", "O"
PROPERTIES = "species:S:1:pos:R:3:kind:S:1:radius:R:1"


def xyz_frames(
    arrays: Mapping[str, NDArray[Any]], scenario: Scenario, rows: NDArray[np.int64]
) -> Iterator[str]:
    """The frames of ``rows`` (indices of the recorded steps), a frame at a time, so that a
    long episode is never held whole as text."""
    brownian = scenario.physics.model == "active_brownian"
    step_s = scenario.physics.step_s if brownian else 1.0
    size = scenario.space.size
    half = size / 2
    box = (
        f'Lattice="{size:g} 0 0 0 {size:g} 0 0 0 {size:g}" Origin="{-half:g} {-half:g} '
        f'{-half:g}" Properties={PROPERTIES} pbc="F F F"'
    )
    units = f"time_unit={'s' if brownian else 'step'} length_unit={'um' if brownian else 'lattice'}"
    robot_radius = scenario.physics.robot_radius_um if brownian else scenario.robots.radius
    cell_radius = scenario.physics.cell_radius_um if brownian else 0.0
    obstacle_radius = float(arrays["obstacle_radius"])
    obstacles = arrays["obstacles"]
    moving = obstacles.shape[0] == arrays["step"].shape[0]
    for row in rows:
        kept = obstacles[row if moving else 0]
        parts = (
            (ROBOT, "robot", robot_radius, arrays["robots"][row]),
            (CELL, "cell", cell_radius, arrays["cells"][row]),
            (OBSTACLE, "obstacle", obstacle_radius, kept),
        )
        count = sum(len(positions) for *_, positions in parts)
        step = int(arrays["step"][row])
        lines = [str(count), f"{box} step={step} time={step * step_s:.9g} {units}"]
        for species, kind, radius, positions in parts:
            lines += [
                f"{species} {x:.9g} {y:.9g} {z:.9g} {kind} {radius:.9g}" for x, y, z in positions
            ]
        yield "\n".join(lines) + "\n"
