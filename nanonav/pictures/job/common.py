"""What every picture of a job shares: its size in pixels, the colours, and the evaluation
episode it reads from a finished ``SimulationResult``."""

from __future__ import annotations

from typing import Literal

import numpy as np
from matplotlib.figure import Figure
from numpy.typing import NDArray

from nanonav.engine import SimulationResult, Trajectory
from nanonav.engine.fields import biomarker_of
from nanonav.pictures.figure import DPI, new_figure
from nanonav.scenario import Scenario

ColourScale = Literal["auto", "linear", "log"]

PICTURE_PIXELS: dict[str, tuple[int, int]] = {
    "heatmap_xy": (640, 620),
    "heatmap_xz": (640, 620),
    "heatmap_yz": (640, 620),
    "heatmap_all": (1520, 540),
    "trajectory": (750, 720),
    "concentration": (800, 600),
    "learning": (900, 600),
    "treatment": (900, 700),
}
"""(width, height) in pixels of each picture, whatever it shows (one robot or ten thousand, a
learner or a baseline, any heatmap resolution); the Q-table's grows with the table."""

# Paths longer than this are thinned to this many points (their last one kept) to draw fast.
MAX_LINE_POINTS = 2000


def length_unit(scenario: Scenario) -> str:
    """What lengths are measured in: µm in the active Brownian physics, else simulation units."""
    return "µm" if scenario.physics.model == "active_brownian" else "length units"


def counted(count: int, word: str, plural: str | None = None) -> str:
    """``1 cancer cell``, ``2 cancer cells``: a count with its noun in the right number."""
    return f"{count} {word if count == 1 else plural or word + 's'}"


def step_label(scenario: Scenario) -> str:
    """A step axis's label: in the active Brownian physics it says how long a step lasts."""
    if scenario.physics.model == "active_brownian":
        return f"step (of {scenario.physics.step_s:g} s)"
    return "step"


def duration(scenario: Scenario, steps: int) -> str:
    """``steps`` steps as the scenario speaks of time: seconds in the active Brownian physics
    (``60 s``), steps in the lattice (``6,000 steps``)."""
    if scenario.physics.model == "active_brownian":
        return f"{steps * scenario.physics.step_s:.3g} s"
    return f"{steps:,} step{'' if steps == 1 else 's'}"


def reach_summary(scenario: Scenario, trajectory: Trajectory) -> str:
    """Who reached a cell in the evaluation episode, and when: the same words in every
    picture's title, the time in the physics' own unit."""
    n = len(trajectory.reached)
    reached = int(np.count_nonzero(trajectory.reached))
    if n == 1:
        if reached:
            return f"reached a cell after {duration(scenario, int(trajectory.robot_steps[0]))}"
        return f"did not reach a cell within {duration(scenario, trajectory.length)}"
    return f"{reached} of {n} reached a cell within {duration(scenario, trajectory.length)}"


def recorded_world(result: SimulationResult) -> str:
    """Which evaluation the pictures of one episode show: the engine records the first of the
    run's evaluation worlds, so a title names it as one of them ("evaluation world 1 of 8"),
    not as the evaluation that Table 1 averages."""
    worlds = len(result.worlds)
    return "evaluation episode" if worlds <= 1 else f"evaluation world 1 of {worlds}"


def world_times(result: SimulationResult) -> list[float]:
    """Every evaluation world's time to reach a cell (Table 1's ``total_steps``), in steps, the
    recorded (drawn) world first."""
    return [float(w["total_steps"]) for w in result.worlds if "total_steps" in w]


def beside_the_worlds(result: SimulationResult) -> str:
    """The drawn world's time to reach a cell (Table 1's ``total_steps``) beside the mean and
    range over every evaluation world, so that one world is not read as the typical one; empty
    for a run of one world."""
    values = world_times(result)
    if len(values) < 2:
        return ""
    ph = result.scenario.physics
    seconds = ph.model == "active_brownian"
    scale, unit = (ph.step_s, "s") if seconds else (1.0, "steps")

    def number(steps: float) -> str:
        return f"{steps * scale:,.3g}" if seconds else f"{steps:,.4g}"

    return (
        f"time to reach: this world {number(values[0])}, mean of {len(values)} worlds "
        f"{number(float(np.mean(values)))} ({number(min(values))}-{number(max(values))}) {unit}"
    )


def concentration_unit(scenario: Scenario) -> str:
    """nM in the active Brownian physics, else arbitrary units."""
    return "nM" if scenario.physics.model == "active_brownian" else "a.u."


ROBOT_BLUE = "tab:blue"
CELL_RED = "tab:red"
START_GREEN = "tab:green"


def sized_figure(name: str) -> Figure:
    """An empty figure of the picture ``name``'s size (``PICTURE_PIXELS``)."""
    width, height = PICTURE_PIXELS[name]
    return new_figure(width / DPI, height / DPI)


def evaluation_trajectory(result: SimulationResult) -> Trajectory:
    """The recorded evaluation episode, or ``ValueError`` for a run stopped before it."""
    if result.trajectory is None:
        raise ValueError(
            "this result has no evaluation episode to draw (the run was stopped before it "
            "finished); only the learning curve can be drawn"
        )
    return result.trajectory


def last_row(trajectory: Trajectory, robot: int) -> int:
    """The history row that shows ``robot`` where it stopped: the first row at or after its last
    step (rows may be ``stride`` steps apart, and a stopped robot stays put)."""
    row = int(np.searchsorted(trajectory.step, trajectory.robot_steps[robot], side="left"))
    return min(row, len(trajectory.step) - 1)


def thin(path: NDArray[np.float64]) -> NDArray[np.float64]:
    """At most ``MAX_LINE_POINTS`` rows of a path, always keeping its last point."""
    if len(path) <= MAX_LINE_POINTS:
        return path
    stride = int(np.ceil(len(path) / MAX_LINE_POINTS))
    return np.concatenate([path[::stride], path[-1:]])


def resolve_scale(result: SimulationResult, scale: ColourScale) -> Literal["linear", "log"]:
    """``scale``, with ``"auto"`` made linear for the Gaussian field and logarithmic for the
    others, which span decades (the concentration picture also takes a log axis for a Gaussian
    field felt over decades: ``concentration.spans_decades``)."""
    if scale != "auto":
        return scale
    return "linear" if biomarker_of(result.scenario).model == "gaussian" else "log"
