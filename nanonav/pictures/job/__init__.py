"""The pictures of a job, as PNG bytes: the paper's Figures 3, 4 and 5 (``trajectory``,
``concentration``, ``heatmap``), the ``learning`` curve, the learned ``qtable`` and the swarm's
``treatment``, a module each; ``render`` and ``render_all`` draw them by name.

These modules only read a finished ``SimulationResult`` (or, for the Q-table, its arrays). Each
PNG is exactly ``PICTURE_PIXELS`` in size (no tight bounding box), which clients can rely on;
the Q-table's grows with the table.
"""

from __future__ import annotations

from nanonav.engine import SimulationResult
from nanonav.pictures.figure import png
from nanonav.pictures.job.common import PICTURE_PIXELS, ColourScale, resolve_scale
from nanonav.pictures.job.concentration import concentration_png
from nanonav.pictures.job.heatmap import (
    HEATMAP_RESOLUTION,
    MAX_HEATMAP_RESOLUTION,
    MIN_HEATMAP_RESOLUTION,
    Plane,
    heatmap_figure,
    heatmap_png,
    heatmap_slices,
)
from nanonav.pictures.job.learning import learning_png
from nanonav.pictures.job.qtable import learned_qtable_png, qtable_png
from nanonav.pictures.job.trajectory import trajectory_png
from nanonav.pictures.job.treatment import has_treatment, treatment_drawn, treatment_png

__all__ = [
    "HEATMAP_RESOLUTION",
    "MAX_HEATMAP_RESOLUTION",
    "MIN_HEATMAP_RESOLUTION",
    "OPTIONAL_PICTURES",
    "PICTURE_NAMES",
    "PICTURE_PIXELS",
    "VERSIONS",
    "ColourScale",
    "qtable_png",
    "render",
    "render_all",
    "treatment_drawn",
    "version",
]

PICTURE_NAMES: tuple[str, ...] = (
    "heatmap_xy",
    "heatmap_xz",
    "heatmap_yz",
    "heatmap_all",
    "trajectory",
    "concentration",
    "learning",
    "qtable",
    "treatment",
)
"""The keys of ``render_all``: also the file names (``<name>.png``) the command line writes;
``qtable`` only for a result that learned a Q-table (Q-learning), ``treatment`` only for one
whose robots deliver payloads (``treatment.has_treatment``)."""

OPTIONAL_PICTURES = frozenset({"qtable", "treatment"})
"""The pictures only some results have (``render`` refuses the others with ``ValueError``)."""

VERSIONS: dict[str, int] = {
    "learning": 3,
    "qtable": 2,
    "trajectory": 4,
    "treatment": 3,
    "concentration": 3,
    "heatmap_xy": 2,
    "heatmap_xz": 2,
    "heatmap_yz": 2,
    "heatmap_all": 2,
}
"""The version of each picture's drawing, for the pictures past their first (the others are at
1). It goes up when a picture drawn before would now be drawn differently, so that a copy kept
of the older drawing is not served again. 2: ``learning`` of a result stored without its
trajectory shows the greedy evaluation too; ``trajectory`` of a swarm's result colours its
robots by what they did and the signal they read, and its treated cells apart. 3: an active
Brownian ``learning`` gives each episode's length in seconds. ``qtable`` 2: each greedy dot's
area is its action gap, given beside the visits. ``trajectory`` 3, ``treatment`` 2 and
``concentration`` 2: lengths in µm (not um), an active Brownian cell drawn to
scale, a swarm that delivers no payload (robots that only take up space) drawn as the paper's,
counts in the right number, a payload axis from 0. ``trajectory`` 4, ``treatment`` 3,
``concentration`` 3: a run of many evaluation worlds names the one drawn ("evaluation world 1
of 8"), and the trajectory gives its time to reach beside their mean. The heatmaps' 2: the
colour scale chosen from the slices' values (``heatmap.SCALE_QUANTILES``), not topped by the
concentration at a cell, and the world named."""


def version(name: str) -> int:
    """The version of the drawing of the picture ``name`` (``VERSIONS``)."""
    return VERSIONS.get(name, 1)


def render(
    result: SimulationResult,
    name: str,
    *,
    scale: ColourScale = "auto",
    at: float | None = None,
    resolution: int = HEATMAP_RESOLUTION,
) -> bytes:
    """The one picture ``name`` (one of ``PICTURE_NAMES``), drawn on its own; ``at`` and
    ``resolution`` choose a heatmap's slice and grid (``heatmap_png``)."""
    planes: dict[str, Plane] = {"heatmap_xy": "xy", "heatmap_xz": "xz", "heatmap_yz": "yz",
                                "heatmap_all": "all"}  # fmt: skip
    if name in planes:
        return heatmap_png(result, planes[name], at=at, resolution=resolution, scale=scale)
    drawers = {"trajectory": trajectory_png, "concentration": concentration_png,
               "learning": learning_png, "qtable": learned_qtable_png,
               "treatment": treatment_png}  # fmt: skip
    if name not in drawers:
        raise ValueError(f"there is no picture {name!r}; there are {', '.join(PICTURE_NAMES)}")
    if at is not None or resolution != HEATMAP_RESOLUTION:
        raise ValueError(f"only heatmaps take at and resolution, not {name!r}")
    return drawers[name](result)


def render_all(result: SimulationResult, *, scale: ColourScale = "auto") -> dict[str, bytes]:
    """Every picture the result has, keyed by ``PICTURE_NAMES`` (the Q-table only if it learned
    one, the treatment only if its robots deliver payloads); the field is evaluated once for the
    four heatmaps."""
    planes = ("xy", "xz", "yz")
    slices = heatmap_slices(result, planes)
    resolved = resolve_scale(result, scale)
    pictures = {
        f"heatmap_{p}": png(heatmap_figure(result, {p: slices[p]}, resolved)) for p in planes
    }
    pictures["heatmap_all"] = png(heatmap_figure(result, slices, resolved))
    pictures["trajectory"] = trajectory_png(result)
    pictures["concentration"] = concentration_png(result)
    pictures["learning"] = learning_png(result)
    if result.qtable is not None:
        pictures["qtable"] = learned_qtable_png(result)
    if has_treatment(result):
        pictures["treatment"] = treatment_png(result)
    return {name: pictures[name] for name in PICTURE_NAMES if name in pictures}
