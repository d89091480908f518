"""What a job's pictures are, as plain data: their names, the versions of their drawings, a
heatmap's grid, and whether a job has the treatment picture. The API reads them to list and
link a job's pictures without loading what draws them (``drawing``) or the engine."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

# Heatmap grids are HEATMAP_RESOLUTION pixels per side unless asked otherwise, within these.
HEATMAP_RESOLUTION = 120
MIN_HEATMAP_RESOLUTION = 20
MAX_HEATMAP_RESOLUTION = 400

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


def treatment_drawn(scenario: Mapping[str, Any]) -> bool:
    """Whether a job of the resolved scenario ``scenario`` (as JSON) has the treatment picture
    (``delivers_payloads``), read off the plain document so that listing jobs validates none."""
    cells = scenario.get("cells") or {}
    communication = scenario.get("communication") or {}
    return cells.get("capacity") is not None or (communication.get("model") or "none") != "none"
