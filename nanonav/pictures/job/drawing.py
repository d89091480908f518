"""A job's pictures drawn by name: ``render`` one, ``render_all`` every one a result has."""

from __future__ import annotations

from nanonav.engine import SimulationResult
from nanonav.pictures.figure import png
from nanonav.pictures.job.catalogue import HEATMAP_RESOLUTION, PICTURE_NAMES
from nanonav.pictures.job.common import ColourScale, resolve_scale
from nanonav.pictures.job.concentration import concentration_png
from nanonav.pictures.job.heatmap import Plane, heatmap_figure, heatmap_png, heatmap_slices
from nanonav.pictures.job.learning import learning_png
from nanonav.pictures.job.qtable import learned_qtable_png
from nanonav.pictures.job.trajectory import trajectory_png
from nanonav.pictures.job.treatment import has_treatment, treatment_png


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
