"""The heatmap (Figure 5): the field in a plane, where and as finely as it is asked for."""

from typing import Literal

import numpy as np
import pytest
from matplotlib.figure import Figure
from numpy.typing import NDArray

from nanonav.engine import SimulationResult
from nanonav.pictures.figure import png
from nanonav.pictures.job.common import ColourScale, resolve_scale
from nanonav.pictures.job.heatmap import (
    MAX_HEATMAP_PATHS,
    SCALE_QUANTILES,
    Plane,
    heatmap_figure,
    heatmap_png,
    heatmap_slices,
)
from tests.pictures.job.results import EXPECTED_SIZE, assert_picture, decode, panel_titles


@pytest.mark.parametrize("plane", ["xy", "xz", "yz", "all"])
@pytest.mark.parametrize("scale", ["linear", "log"])
def test_heatmap_draws_each_plane_on_either_scale(
    single: SimulationResult, plane: Plane, scale: ColourScale
) -> None:
    drawn = heatmap_png(single, plane, scale=scale, resolution=40)
    assert_picture(drawn, EXPECTED_SIZE[f"heatmap_{plane}"])


def test_heatmap_is_brightest_at_the_target_cell(single: SimulationResult) -> None:
    trajectory = single.trajectory
    assert trajectory is not None
    cut = heatmap_slices(single, ("xy",), 101)["xy"]
    row, col = np.unravel_index(np.argmax(cut.grid), cut.grid.shape)
    cell = trajectory.cells[-1, 0]
    spacing = cut.axis[1] - cut.axis[0]
    assert spacing == pytest.approx(single.scenario.space.size / 101)
    assert cut.axis[0] == pytest.approx(-single.scenario.space.size / 2 + spacing / 2)
    assert cut.level == pytest.approx(cell[2])
    assert abs(cut.axis[col] - cell[0]) <= spacing
    assert abs(cut.axis[row] - cell[1]) <= spacing


def test_auto_scale_is_linear_for_gaussian_and_log_for_the_others(
    single: SimulationResult, swarm: SimulationResult
) -> None:
    assert resolve_scale(single, "auto") == "linear"
    assert resolve_scale(swarm, "auto") == "log"
    assert resolve_scale(swarm, "linear") == "linear"


def heatmap_pixels(figure: Figure) -> NDArray[np.float32]:
    """The RGB pixels inside the first slice's axes, as the PNG shows them."""
    image = decode(png(figure))
    box = figure.axes[0].get_window_extent()
    top = image.shape[0] - int(np.ceil(box.y1))
    bottom = image.shape[0] - int(np.floor(box.y0))
    return image[top + 2 : bottom - 2, int(np.ceil(box.x0)) + 2 : int(box.x1) - 2, :3]


def test_the_heatmap_draws_the_paths_projected_on_the_slice(swarm: SimulationResult) -> None:
    trajectory = swarm.trajectory
    assert trajectory is not None
    slices = heatmap_slices(swarm, ("xz",), 40)
    ax = heatmap_figure(swarm, slices, "log").axes[0]
    paths = ax.get_lines()
    assert trajectory.robots.shape[1] > MAX_HEATMAP_PATHS
    assert len(paths) == MAX_HEATMAP_PATHS  # the field stays visible under them
    end = int(trajectory.robot_steps[3])
    x, z = paths[3].get_data()
    assert isinstance(x, np.ndarray) and isinstance(z, np.ndarray)
    assert x[-1] == pytest.approx(trajectory.robots[end, 3, 0])
    assert z[-1] == pytest.approx(trajectory.robots[end, 3, 2])


def test_the_heatmap_slice_is_where_it_is_asked_for(swarm: SimulationResult) -> None:
    slices = heatmap_slices(swarm, ("xy", "yz"), 30, at=-7.5)
    assert [s.level for s in slices.values()] == [-7.5, -7.5]
    figure = heatmap_figure(swarm, slices, "log", through_target=False)
    assert panel_titles(figure)[:2] == ["XY plane at z = -7.5", "YZ plane at x = -7.5"]
    shown = figure.axes[0].images[0].get_array()
    assert shown is not None and shown.shape == (30, 30)
    assert "at the chosen level" in figure.get_suptitle()
    drawn = heatmap_png(swarm, "xy", at=-7.5, resolution=30)
    assert_picture(drawn, EXPECTED_SIZE["heatmap_xy"])
    assert drawn != heatmap_png(swarm, "xy", resolution=30)


@pytest.mark.parametrize(
    ("at", "resolution", "message"),
    [
        (25.5, 120, r"at must be within \[-25, 25\]"),
        (-26.0, 120, r"at must be within \[-25, 25\]"),
        (float("nan"), 120, "at must be within"),
        (None, 19, r"resolution must be within \[20, 400\]"),
        (None, 401, r"resolution must be within \[20, 400\]"),
    ],
)
def test_the_heatmap_refuses_a_slice_outside_the_cube_or_a_resolution_out_of_bounds(
    single: SimulationResult, at: float | None, resolution: int, message: str
) -> None:
    with pytest.raises(ValueError, match=message):
        heatmap_png(single, "xy", at=at, resolution=resolution)


def typical_run(pixels: NDArray[np.float32]) -> float:
    """The length of the run of one colour, along its row, that the median pixel lies in: the
    width of a grid square where the field changes faster than the colour map's steps (the
    thin paths drawn over the field hold few pixels and do not move it)."""
    lengths = []
    for row in np.round(pixels * 255).astype(int):
        changes = np.flatnonzero(np.any(row[1:] != row[:-1], axis=-1)) + 1
        runs = np.diff(np.concatenate([[0], changes, [len(row)]]))
        lengths.append(np.repeat(runs, runs))
    return float(np.median(np.concatenate(lengths)))


def test_the_heatmap_resolution_sets_the_size_of_its_pixels(swarm: SimulationResult) -> None:
    def run_at(resolution: int) -> tuple[float, int]:
        slices = heatmap_slices(swarm, ("xy",), resolution)
        pixels = heatmap_pixels(heatmap_figure(swarm, slices, "log"))
        return typical_run(pixels), pixels.shape[1]

    (coarse, width), (medium, _), (fine, _) = run_at(20), run_at(60), run_at(400)
    assert coarse == pytest.approx(width / 20, rel=0.2)  # about 23 screen pixels a square
    assert medium == pytest.approx(width / 60, rel=0.2)
    assert fine < medium / 1.5


def test_the_colour_scale_is_chosen_from_the_drawn_values(
    single: SimulationResult, swarm: SimulationResult
) -> None:
    """Topped by the concentration at a cell, a field that falls over decades drew the whole
    cube in the darkest colour: the scale runs between quantiles of the slices' values, and
    the colour bar's arrows say what lies beyond."""
    cases: tuple[tuple[SimulationResult, Literal["linear", "log"]], ...] = (
        (single, "linear"),
        (swarm, "log"),
    )
    for result, scale in cases:
        slices = heatmap_slices(result, ("xy",), 60)
        figure = heatmap_figure(result, slices, scale)
        image = figure.axes[0].get_images()[0]
        values = slices["xy"].grid
        positive = values[values > 0] if scale == "log" else values
        low, high = np.quantile(positive, SCALE_QUANTILES)
        assert image.norm.vmax == pytest.approx(high)
        assert image.norm.vmin == pytest.approx(low if scale == "log" else 0.0)
        colourbar = figure.axes[-1]
        assert colourbar.get_ylabel().startswith("biomarker concentration")
    # the inverse-square field, decades below its cells nearly everywhere, spans the colour
    # map: neither all dark (as it was) nor all bright
    shades = np.asarray(image.norm(values)).clip(0, 1)
    assert np.mean(shades < 0.1) < 0.5 and np.quantile(shades, 0.9) > 0.5


def test_a_slice_far_from_the_cells_reads_its_own_values(single: SimulationResult) -> None:
    trajectory = single.trajectory
    assert trajectory is not None
    half = single.scenario.space.size / 2
    far = -half if trajectory.cells[-1, 0, 2] > 0 else half
    through = heatmap_slices(single, ("xy",), 60)["xy"].grid
    away = heatmap_slices(single, ("xy",), 60, at=far)["xy"].grid
    assert away.max() < through.max()
    figure = heatmap_figure(single, {"xy": heatmap_slices(single, ("xy",), 60, at=far)["xy"]},
                            "linear", through_target=False)  # fmt: skip
    assert figure.axes[0].get_images()[0].norm.vmax == pytest.approx(
        np.quantile(away, SCALE_QUANTILES[1])
    )
