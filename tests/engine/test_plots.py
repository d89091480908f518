"""Pictures: every PNG decodes, has the promised size and shows something."""

import io
from typing import Any

import numpy as np
import pytest
from matplotlib.image import imread
from numpy.typing import NDArray

from nanonav import plots
from nanonav.engine import Progress, SimulationResult, simulate
from nanonav.scenario import Scenario

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"

# Size in pixels (width, height) of each picture: figure size in inches x figures.DPI.
EXPECTED_SIZE = {
    "heatmap_xy": (640, 620),
    "heatmap_xz": (640, 620),
    "heatmap_yz": (640, 620),
    "heatmap_all": (1520, 540),
    "trajectory": (750, 680),
    "concentration": (800, 480),
    "learning": (900, 600),
}


def scenario(**fields: Any) -> Scenario:
    return Scenario.model_validate(fields)


@pytest.fixture(scope="module")
def swarm() -> SimulationResult:
    return simulate(
        scenario(
            preset="paper-swarm",
            seed=5,
            learning={"episodes": 2, "max_steps": 200},
            biomarker={"model": "inverse_square"},
        )
    )


@pytest.fixture(scope="module")
def single() -> SimulationResult:
    return simulate(
        scenario(preset="paper-single", seed=2, learning={"episodes": 2, "max_steps": 200})
    )


def decode(png: bytes) -> NDArray[np.float32]:
    assert png.startswith(PNG_SIGNATURE)
    image: NDArray[np.float32] = imread(io.BytesIO(png), format="png")
    return image


def assert_picture(png: bytes, size: tuple[int, int]) -> None:
    image = decode(png)
    height, width = image.shape[:2]
    assert (width, height) == size
    rgb = image[..., :3]
    assert float(rgb.std()) > 0.05
    channels = np.round(rgb * 255).astype(np.uint32)
    packed = (channels[..., 0] << 16) | (channels[..., 1] << 8) | channels[..., 2]
    assert len(np.unique(packed)) > 20


def test_render_all_gives_every_named_picture_at_its_size(swarm: SimulationResult) -> None:
    pictures = plots.render_all(swarm)
    assert tuple(pictures) == plots.PICTURE_NAMES
    for name, png in pictures.items():
        assert_picture(png, EXPECTED_SIZE[name])


def test_single_robot_pictures_render_at_their_size(single: SimulationResult) -> None:
    assert_picture(plots.trajectory_png(single), EXPECTED_SIZE["trajectory"])
    assert_picture(plots.concentration_png(single), EXPECTED_SIZE["concentration"])
    assert_picture(plots.learning_png(single), EXPECTED_SIZE["learning"])


@pytest.mark.parametrize("plane", ["xy", "xz", "yz", "all"])
@pytest.mark.parametrize("scale", ["linear", "log"])
def test_heatmap_draws_each_plane_on_either_scale(
    single: SimulationResult, plane: plots.Plane, scale: plots.ColourScale
) -> None:
    png = plots.heatmap_png(single, plane, scale=scale, resolution=40)
    assert_picture(png, EXPECTED_SIZE[f"heatmap_{plane}"])


def test_heatmap_is_brightest_at_the_target_cell(single: SimulationResult) -> None:
    trajectory = single.trajectory
    assert trajectory is not None
    slices = plots._slices(single, ("xy",), 101)
    grid = slices["xy"]
    row, col = np.unravel_index(np.argmax(grid), grid.shape)
    half = single.scenario.space.size / 2
    axis = np.linspace(-half, half, 101)
    cell = trajectory.cells[-1, 0]
    spacing = axis[1] - axis[0]
    assert abs(axis[col] - cell[0]) <= spacing
    assert abs(axis[row] - cell[1]) <= spacing


def test_auto_scale_is_linear_for_gaussian_and_log_for_the_others(
    single: SimulationResult, swarm: SimulationResult
) -> None:
    assert plots._resolve_scale(single, "auto") == "linear"
    assert plots._resolve_scale(swarm, "auto") == "log"
    assert plots._resolve_scale(swarm, "linear") == "linear"


def test_stopped_run_draws_only_its_learning_curve() -> None:
    def stop_after_two_episodes(progress: Progress) -> bool:
        return progress.episode < 2

    # 50 random walkers: an episode is about half of the work between two progress reports
    walkers = scenario(
        robots={"count": 50, "policy": "random"}, learning={"episodes": 10, "max_steps": 1000}
    )
    stopped = simulate(walkers, stop_after_two_episodes)
    assert not stopped.completed and stopped.trajectory is None
    assert 2 <= len(stopped.episodes) < 10
    assert_picture(plots.learning_png(stopped), EXPECTED_SIZE["learning"])
    for draw in (plots.trajectory_png, plots.concentration_png, plots.heatmap_png):
        with pytest.raises(ValueError, match="no evaluation episode"):
            draw(stopped)
    with pytest.raises(ValueError, match="no evaluation episode"):
        plots.render_all(stopped)


def test_learning_curve_needs_at_least_one_episode() -> None:
    # Enough robots that the first report comes mid-way through the first episode.
    crowd = scenario(robots={"count": 2000, "policy": "random"}, learning={"episodes": 3})
    stopped = simulate(crowd, lambda _: False)
    assert stopped.episodes == [] and stopped.trajectory is None
    with pytest.raises(ValueError, match="no finished episode"):
        plots.learning_png(stopped)


def test_large_swarm_draws_a_subset_of_paths() -> None:
    big = simulate(
        scenario(
            seed=1,
            robots={"count": plots.MAX_ROBOT_PATHS + 10, "policy": "gradient"},
            obstacles={"count": plots.MAX_SPHERES + 5, "radius": 0.5},
            learning={"episodes": 0, "max_steps": 60},
        )
    )
    assert_picture(plots.trajectory_png(big), EXPECTED_SIZE["trajectory"])
    assert_picture(plots.learning_png(big), EXPECTED_SIZE["learning"])


def test_a_stored_result_draws_the_same_pictures_as_the_live_one(swarm: SimulationResult) -> None:
    stored = SimulationResult.from_stored(swarm.to_dict(), swarm.arrays())
    assert stored.trajectory is not None and swarm.trajectory is not None
    assert stored.trajectory.stride == swarm.trajectory.stride
    for name in ("heatmap_xy", "trajectory", "learning"):
        assert plots.render(stored, name) == plots.render(swarm, name)


def test_render_names_every_picture_and_refuses_others(single: SimulationResult) -> None:
    for name in plots.PICTURE_NAMES:
        assert_picture(plots.render(single, name), EXPECTED_SIZE[name])
    with pytest.raises(ValueError, match="no picture 'heatmap_xx'"):
        plots.render(single, "heatmap_xx")
