"""The pictures of a job, as PNG bytes: the paper's Figures 3, 4 and 5 (``trajectory``,
``concentration``, ``heatmap``), the ``learning`` curve, the learned ``qtable`` and the swarm's
``treatment``, a module each; ``render`` and ``render_all`` draw them by name.

These modules only read a finished ``SimulationResult`` (or, for the Q-table, its arrays). Each
PNG is exactly ``PICTURE_PIXELS`` in size (no tight bounding box), which clients can rely on;
the Q-table's grows with the table.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from nanonav.lazy import names_from

if TYPE_CHECKING:
    from nanonav.pictures.job.catalogue import HEATMAP_RESOLUTION as HEATMAP_RESOLUTION
    from nanonav.pictures.job.catalogue import MAX_HEATMAP_RESOLUTION as MAX_HEATMAP_RESOLUTION
    from nanonav.pictures.job.catalogue import MIN_HEATMAP_RESOLUTION as MIN_HEATMAP_RESOLUTION
    from nanonav.pictures.job.catalogue import OPTIONAL_PICTURES as OPTIONAL_PICTURES
    from nanonav.pictures.job.catalogue import PICTURE_NAMES as PICTURE_NAMES
    from nanonav.pictures.job.catalogue import VERSIONS as VERSIONS
    from nanonav.pictures.job.catalogue import treatment_drawn as treatment_drawn
    from nanonav.pictures.job.catalogue import version as version
    from nanonav.pictures.job.common import PICTURE_PIXELS as PICTURE_PIXELS
    from nanonav.pictures.job.common import ColourScale as ColourScale
    from nanonav.pictures.job.drawing import render as render
    from nanonav.pictures.job.drawing import render_all as render_all
    from nanonav.pictures.job.qtable import qtable_png as qtable_png

# where each public name lives: the plain data in ``catalogue``, the drawing elsewhere
_HOMES = {
    "HEATMAP_RESOLUTION": "catalogue",
    "MAX_HEATMAP_RESOLUTION": "catalogue",
    "MIN_HEATMAP_RESOLUTION": "catalogue",
    "OPTIONAL_PICTURES": "catalogue",
    "PICTURE_NAMES": "catalogue",
    "PICTURE_PIXELS": "common",
    "VERSIONS": "catalogue",
    "ColourScale": "common",
    "qtable_png": "qtable",
    "render": "drawing",
    "render_all": "drawing",
    "treatment_drawn": "catalogue",
    "version": "catalogue",
}
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


# imported when first asked for: the package loads none of its modules itself
__getattr__ = names_from(__name__, _HOMES, globals())
