"""Pictures: every PNG decodes, has the promised size and shows something."""

import io
import typing
from typing import Any

import matplotlib
import numpy as np
import pytest
from matplotlib.container import ErrorbarContainer
from matplotlib.figure import Figure
from matplotlib.image import imread
from mpl_toolkits.mplot3d import proj3d
from numpy.typing import NDArray

from nanonav import plots
from nanonav.engine import Progress, SimulationResult, Trajectory, qlearning, simulate
from nanonav.scenario import Policy, Scenario

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"

# Size in pixels (width, height) of each picture: figure size in inches x figures.DPI.
EXPECTED_SIZE = {
    "heatmap_xy": (640, 620),
    "heatmap_xz": (640, 620),
    "heatmap_yz": (640, 620),
    "heatmap_all": (1520, 540),
    "trajectory": (750, 720),
    "concentration": (800, 600),
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
    cut = plots.heatmap_slices(single, ("xy",), 101)["xy"]
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
    assert not any(ax.containers for ax in plots.learning_figure(stopped).axes)  # no evaluation
    for draw in (plots.trajectory_png, plots.concentration_png, plots.heatmap_png):
        with pytest.raises(ValueError, match="no evaluation episode"):
            draw(stopped)
    with pytest.raises(ValueError, match="no evaluation episode"):
        plots.render_all(stopped)


@pytest.mark.parametrize("policy", typing.get_args(Policy))
def test_every_policy_draws_its_learning_curve(policy: str) -> None:
    run = simulate(
        scenario(
            seed=3, robots={"count": 3, "policy": policy}, learning={"episodes": 2, "max_steps": 80}
        )
    )
    assert_picture(plots.learning_png(run), EXPECTED_SIZE["learning"])


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
            cells={"count": plots.MAX_CELL_PATHS + 3},
            obstacles={"count": plots.COARSE_SPHERES_FROM + 5, "radius": 0.5},
            learning={"episodes": 0, "max_steps": 60},
            evaluation={"worlds": 3},
        )
    )
    figure = plots.trajectory_figure(big)
    colours = [line.get_color() for line in figure.axes[0].get_lines()]
    assert colours.count("tab:blue") == plots.MAX_ROBOT_PATHS
    assert colours.count("tab:red") == plots.MAX_CELL_PATHS
    assert f"paths of the first {plots.MAX_ROBOT_PATHS} robots" in figure.axes[0].get_title()
    assert_picture(plots.trajectory_png(big), EXPECTED_SIZE["trajectory"])
    assert_picture(plots.learning_png(big), EXPECTED_SIZE["learning"])
    assert_picture(plots.concentration_png(big), EXPECTED_SIZE["concentration"])


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


def result_of(trajectory: Trajectory, **fields: Any) -> SimulationResult:
    """A result holding only ``trajectory`` (in a scenario of ``fields``), to draw it."""
    return SimulationResult(
        scenario=scenario(**fields), summary={}, robots=[], episodes=[], work={},
        trajectory=trajectory, qtable=None,
    )  # fmt: skip


def made_trajectory(
    robots: NDArray[np.float64],
    cells: NDArray[np.float64],
    steps: list[int],
    reached: list[bool],
    obstacles: NDArray[np.float64] | None = None,
    radius: float = 1.5,
) -> Trajectory:
    """A trajectory of one row per step from positions ``(rows, n, 3)`` and ``(rows, c, 3)``;
    distances are the true ones, the concentration falls off with them."""
    gaps = np.linalg.norm(robots[:, :, None, :] - cells[:, None, :, :], axis=-1)
    distance = gaps.min(axis=2)
    return Trajectory(
        step=np.arange(robots.shape[0]),
        robots=robots,
        cells=cells,
        obstacles=np.zeros((1, 0, 3)) if obstacles is None else obstacles[None],
        concentration=1.0 / (1.0 + distance),
        distance=distance,
        robot_steps=np.array(steps),
        reached=np.array(reached),
        emitter_offsets=np.zeros((cells.shape[1], 1, 3)),
        obstacle_radius=radius,
    )


def panel_titles(figure: Figure) -> list[str]:
    return [ax.get_title() for ax in figure.axes]


# ---------------------------------------------------------------- the learning curve

LEARNER_PANELS = [
    "steps per episode",
    "robots that reached a cell",
    "mean return per robot",
    "exploration rate",
]


def test_a_learner_shows_its_greedy_evaluation_as_a_mean_with_its_interval(
    swarm: SimulationResult,
) -> None:
    figure = plots.learning_figure(swarm)
    assert panel_titles(figure) == LEARNER_PANELS
    steps, success, _, epsilon = figure.axes
    (bar,) = steps.containers
    assert isinstance(bar, ErrorbarContainer)
    x, y = bar.lines[0].get_data()
    assert float(y[0]) == pytest.approx(swarm.summary["episode_steps"])
    spread = swarm.uncertainty["episode_steps"]
    assert spread["ci_high"] > spread["ci_low"]
    (segment,) = bar.lines[2][0].get_segments()
    assert segment[:, 1] == pytest.approx([spread["ci_low"], spread["ci_high"]])
    (rate,) = success.containers
    assert float(rate.lines[0].get_ydata()[0]) == pytest.approx(100 * swarm.summary["success_rate"])
    assert not epsilon.containers  # the evaluation is greedy: no exploration rate to show
    labels = {t.get_text(): t.get_position()[0] for t in epsilon.get_xticklabels()}
    assert labels["greedy\nevaluation"] == pytest.approx(float(x[0]))
    (legend,) = figure.legends
    texts = [t.get_text() for t in legend.get_texts()]
    assert "greedy evaluation, 20 worlds (mean, 95% CI)" in texts


def test_a_baseline_shows_its_trials_without_exploration_or_evaluation() -> None:
    run = simulate(
        scenario(
            seed=4, robots={"count": 3, "policy": "gradient"},
            learning={"episodes": 6, "max_steps": 80}, evaluation={"worlds": 3},
        )
    )  # fmt: skip
    figure = plots.learning_figure(run)
    assert panel_titles(figure) == LEARNER_PANELS[:3]
    assert not any(ax.containers for ax in figure.axes)
    ticks = [t.get_text() for ax in figure.axes for t in ax.get_xticklabels()]
    assert not any("evaluation" in t for t in ticks)
    title = figure.get_suptitle()
    assert title == "Gradient climbing does not learn: 6 training episodes, all trials alike"
    assert_picture(plots.learning_png(run), EXPECTED_SIZE["learning"])


def test_a_baseline_without_training_draws_its_evaluation_worlds_as_trials() -> None:
    run = simulate(
        scenario(
            seed=4, robots={"count": 3, "policy": "rule"},
            learning={"episodes": 0, "max_steps": 80}, evaluation={"worlds": 5},
        )
    )  # fmt: skip
    figure = plots.learning_figure(run)
    steps = figure.axes[0].get_lines()[-1]  # the moving mean over the raw line
    raw = figure.axes[0].get_lines()[0]
    assert raw.get_xdata().tolist() == [0, 1, 2, 3, 4]
    assert raw.get_ydata().tolist() == [w["episode_steps"] for w in run.worlds]
    assert steps.get_ydata() == pytest.approx(plots.moving_mean(raw.get_ydata(), 2))
    assert "5 evaluation worlds as trials" in figure.get_suptitle()
    assert figure.axes[-1].get_xlabel() == "evaluation world"


def test_the_moving_mean_spans_about_an_eighth_of_the_run() -> None:
    windows = [plots.smoothing_window(n) for n in (1, 3, 4, 10, 20, 50, 200, 5000)]
    assert windows == [1, 1, 2, 2, 3, 7, 25, plots.MAX_SMOOTHING_WINDOW]
    mean = plots.moving_mean(np.array([2.0, 4.0, 6.0, 10.0, 0.0]), 3)
    assert mean == pytest.approx([2.0, 3.0, 4.0, 20 / 3, 16 / 3])


def test_a_short_run_gets_a_moving_mean_over_its_faint_raw_values() -> None:
    run = simulate(scenario(seed=6, robots={"count": 4}, learning={"episodes": 8, "max_steps": 80}))
    figure = plots.learning_figure(run)
    raw, mean, *_ = figure.axes[0].get_lines()
    assert raw.get_ydata().tolist() == [e["steps"] for e in run.episodes]
    assert raw.get_alpha() == pytest.approx(0.3)
    assert mean.get_ydata() == pytest.approx(plots.moving_mean(raw.get_ydata(), 2))
    (legend,) = figure.legends
    assert "moving mean of 2" in [t.get_text() for t in legend.get_texts()]


# ---------------------------------------------------------------- concentration and distance


def drifting_cell_and_three_robots() -> Trajectory:
    """A cell drifting along x one unit a step. Robot 0 reaches it at step 1 and stops, so its
    distance then grows; robots 1 and 2 follow 10 and 12 units beside it and never reach."""
    rows = 6
    t = np.arange(rows, dtype=np.float64)
    cells = np.zeros((rows, 1, 3))
    cells[:, 0, 0] = t
    robots = np.zeros((rows, 3, 3))
    robots[:, 0, 0] = np.minimum(t, 1.0)
    robots[0, 0, 0] = -3.0
    robots[:, 1] = np.stack([t, np.full(rows, 10.0), np.zeros(rows)], axis=1)
    robots[:, 2] = np.stack([t, np.full(rows, 12.0), np.zeros(rows)], axis=1)
    return made_trajectory(robots, cells, steps=[1, 5, 5], reached=[True, False, False])


def test_a_robot_searches_until_the_step_it_reached() -> None:
    trajectory = made_trajectory(
        np.zeros((5, 3, 3)), np.ones((5, 1, 3)), steps=[2, 4, 4], reached=[True, True, False]
    )
    searching = plots.searching_mask(trajectory)
    assert searching.sum(axis=1).tolist() == [3, 3, 2, 2, 1]
    assert searching[:, 0].tolist() == [True, True, False, False, False]


def test_the_swarm_picture_follows_only_the_robots_still_searching() -> None:
    trajectory = drifting_cell_and_three_robots()
    stats = plots.searching_stats(trajectory)
    assert stats.searching.tolist() == [3, 2, 2, 2, 2, 2]
    # Robot 0 sits 4 units behind the cell by the end; counted, it would pull the median to 10.
    assert stats.distance[1:, 1] == pytest.approx([11.0] * 5)
    assert stats.distance[1:, 0] == pytest.approx([10.5] * 5)
    assert stats.concentration[1:, 1] == pytest.approx([(1 / 11 + 1 / 13) / 2] * 5)
    figure = plots.concentration_figure(result_of(trajectory, robots={"count": 3}))
    distance, _, count = figure.axes
    assert count.get_title() == "robots still searching (of 3)"
    assert count.get_lines()[0].get_ydata().tolist() == [3, 2, 2, 2, 2, 2]
    assert distance.get_lines()[0].get_ydata() == pytest.approx(stats.distance[:, 1])
    assert "0 of 3 reached" not in figure.get_suptitle()
    assert "1 of 3 reached a cell within 5 steps" in figure.get_suptitle()
    assert_picture(plots.png(figure), EXPECTED_SIZE["concentration"])


def test_one_robot_keeps_the_papers_twin_axes_up_to_its_reach(single: SimulationResult) -> None:
    trajectory = single.trajectory
    assert trajectory is not None and trajectory.reached[0]
    figure = plots.concentration_figure(single)
    concentration, distance = figure.axes
    assert concentration.get_ylabel().startswith("biomarker concentration")
    assert distance.get_ylabel().startswith("distance to the nearest cell")
    (line,) = distance.get_lines()
    assert int(line.get_xdata()[-1]) == int(trajectory.robot_steps[0])
    assert f"reached a cell at step {int(trajectory.robot_steps[0])}" in figure.get_suptitle()


# ---------------------------------------------------------------- the 3-D paths


def test_obstacles_are_meshes_of_spheres_of_their_radius() -> None:
    centres = np.array([[1.0, 2.0, 3.0], [-4.0, 0.0, 5.0]])
    faces, grey = plots.sphere_mesh(centres, 2.5)
    around, poles = plots.sphere_facets(2)
    corners = faces.reshape(2, around * poles, 4, 3)
    radii = np.linalg.norm(corners - centres[:, None, None, :], axis=-1)
    assert radii == pytest.approx(np.full(radii.shape, 2.5))
    assert grey.shape == (2 * around * poles,) and 0.2 <= grey.min() < grey.max() <= 0.7
    assert plots.sphere_facets(1000) == (6, 4)  # a thousand obstacles still draw quickly


def one_obstacle(radius: float) -> SimulationResult:
    """One obstacle of ``radius`` at the centre of the cube, a robot and a cell in corners."""
    robots = np.array([[[-20.0, -20.0, -20.0]], [[-18.0, -20.0, -20.0]]])
    cells = np.array([[[20.0, 20.0, 20.0]], [[20.0, 20.0, 20.0]]])
    trajectory = made_trajectory(
        robots, cells, steps=[1], reached=[False], obstacles=np.zeros((1, 3)), radius=radius
    )
    return result_of(trajectory)


def dark_grey_pixels_round_the_centre(result: SimulationResult) -> int:
    """Obstacle-grey pixels within 100 pixels of where the cube's centre is drawn."""
    figure = plots.trajectory_figure(result)
    image = decode(plots.png(figure))
    ax: Any = figure.axes[0]
    x, y, _ = proj3d.proj_transform(0.0, 0.0, 0.0, ax.get_proj())
    column, row_up = ax.transData.transform((x, y))
    row = image.shape[0] - row_up
    rgb = image[int(row) - 100 : int(row) + 100, int(column) - 100 : int(column) + 100, :3]
    neutral = (rgb.max(axis=-1) - rgb.min(axis=-1)) < 0.02
    return int((neutral & (rgb.mean(axis=-1) < 0.6)).sum())


def test_obstacles_are_drawn_to_scale() -> None:
    small = dark_grey_pixels_round_the_centre(one_obstacle(2.0))
    large = dark_grey_pixels_round_the_centre(one_obstacle(4.0))
    assert small > 200  # a sphere of radius 2 in a cube of 50 is a disc some 20 pixels wide
    assert 3.0 < large / small < 5.0  # twice the radius, four times the area


def test_robot_ends_are_drawn_over_the_cells(swarm: SimulationResult) -> None:
    ax: Any = plots.trajectory_figure(swarm).axes[0]
    assert not ax.computed_zorder
    zorders = {c.get_label(): c.get_zorder() for c in ax.collections}
    assert zorders["robot end, reached"] > zorders["cell at the end"]


def test_a_robot_that_ends_on_its_cell_still_shows() -> None:
    robots = np.array([[[-10.0, 0.0, 0.0]], [[0.0, 0.0, 0.0]]])
    cells = np.zeros((2, 1, 3))
    result = result_of(made_trajectory(robots, cells, steps=[1], reached=[True]))
    figure = plots.trajectory_figure(result)
    image = decode(plots.png(figure))
    ax: Any = figure.axes[0]
    x, y, _ = proj3d.proj_transform(0.0, 0.0, 0.0, ax.get_proj())
    column, row_up = ax.transData.transform((x, y))
    row = int(image.shape[0] - row_up)
    around = np.round(image[row - 5 : row + 6, int(column) - 5 : int(column) + 6, :3] * 255)
    blue = np.all(np.abs(around - [31, 119, 180]) < 30, axis=-1)
    red = np.all(np.abs(around - [214, 39, 40]) < 30, axis=-1)
    # The robot's ring, whole, over the cell's star (under it, some 7 pixels of it show).
    assert blue.sum() > 25 and red.sum() > 5


def test_many_cells_draw_the_paths_of_the_cells_most_reached() -> None:
    rows, count = 3, 10
    cells = np.zeros((rows, count, 3))
    cells[:, :, 0] = np.linspace(-20, 20, count)
    robots = np.zeros((rows, 3, 3))
    robots[:, :2] = cells[:, [7]]  # robots 0 and 1 end on cell 7, robot 2 on cell 3
    robots[:, 2] = cells[:, 3]
    trajectory = made_trajectory(robots, cells, steps=[2, 2, 2], reached=[True, True, True])
    assert plots.reached_cells(trajectory).tolist() == [0, 0, 0, 1, 0, 0, 0, 2, 0, 0]
    assert plots.cells_with_paths(trajectory).tolist() == [0, 1, 3, 7]
    figure = plots.trajectory_figure(result_of(trajectory))
    red = [line for line in figure.axes[0].get_lines() if line.get_color() == "tab:red"]
    assert len(red) == plots.MAX_CELL_PATHS
    assert "paths of the 4 cells most reached drawn" in figure.axes[0].get_title()


# ---------------------------------------------------------------- heatmaps


def heatmap_pixels(figure: Figure) -> NDArray[np.float32]:
    """The RGB pixels inside the first slice's axes, as the PNG shows them."""
    image = decode(plots.png(figure))
    box = figure.axes[0].get_window_extent()
    top = image.shape[0] - int(np.ceil(box.y1))
    bottom = image.shape[0] - int(np.floor(box.y0))
    return image[top + 2 : bottom - 2, int(np.ceil(box.x0)) + 2 : int(box.x1) - 2, :3]


def test_the_heatmap_draws_the_paths_projected_on_the_slice(swarm: SimulationResult) -> None:
    trajectory = swarm.trajectory
    assert trajectory is not None
    slices = plots.heatmap_slices(swarm, ("xz",), 40)
    ax = plots.heatmap_figure(swarm, slices, "log").axes[0]
    paths = ax.get_lines()
    assert trajectory.robots.shape[1] > plots.MAX_HEATMAP_PATHS
    assert len(paths) == plots.MAX_HEATMAP_PATHS  # the field stays visible under them
    end = int(trajectory.robot_steps[3])
    x, z = paths[3].get_data()
    assert x[-1] == pytest.approx(trajectory.robots[end, 3, 0])
    assert z[-1] == pytest.approx(trajectory.robots[end, 3, 2])


def test_the_heatmap_slice_is_where_it_is_asked_for(swarm: SimulationResult) -> None:
    slices = plots.heatmap_slices(swarm, ("xy", "yz"), 30, at=-7.5)
    assert [s.level for s in slices.values()] == [-7.5, -7.5]
    figure = plots.heatmap_figure(swarm, slices, "log", through_target=False)
    assert panel_titles(figure)[:2] == ["XY plane at z = -7.5", "YZ plane at x = -7.5"]
    assert figure.axes[0].images[0].get_array().shape == (30, 30)
    assert "at the chosen level" in figure.get_suptitle()
    png = plots.heatmap_png(swarm, "xy", at=-7.5, resolution=30)
    assert_picture(png, EXPECTED_SIZE["heatmap_xy"])
    assert png != plots.heatmap_png(swarm, "xy", resolution=30)


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
        plots.heatmap_png(single, "xy", at=at, resolution=resolution)


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
        slices = plots.heatmap_slices(swarm, ("xy",), resolution)
        pixels = heatmap_pixels(plots.heatmap_figure(swarm, slices, "log"))
        return typical_run(pixels), pixels.shape[1]

    (coarse, width), (medium, _), (fine, _) = run_at(20), run_at(60), run_at(400)
    assert coarse == pytest.approx(width / 20, rel=0.2)  # about 23 screen pixels a square
    assert medium == pytest.approx(width / 60, rel=0.2)
    assert fine < medium / 1.5


def test_a_slice_far_from_the_cells_is_darker(single: SimulationResult) -> None:
    trajectory = single.trajectory
    assert trajectory is not None
    half = single.scenario.space.size / 2
    far = -half if trajectory.cells[-1, 0, 2] > 0 else half

    def brightness(at: float | None) -> float:
        slices = plots.heatmap_slices(single, ("xy",), 60, at=at)
        figure = plots.heatmap_figure(single, slices, "linear", through_target=at is None)
        return float(heatmap_pixels(figure).mean())

    through, away = brightness(None), brightness(far)
    assert away < through - 0.05
    # Scaled to the concentration at the cell, the far slice is the colour map's darkest.
    darkest = float(np.mean(matplotlib.colormaps["viridis"](0.0)[:3]))
    assert away == pytest.approx(darkest, abs=0.01)


# ---------------------------------------------------------------- the Q-table picture

# (width, height) in pixels: the figure grows with the table.
QTABLE_SIZE = {"behaviors": (780, 1500), "directions": (1070, 1230)}
UNVISITED_GREY = 209  # 0.82 x 255, the grey of states never visited


def random_table(
    actions: str, unvisited: int = 0, seed: int = 0
) -> tuple[list[str], list[str], NDArray[np.float64], NDArray[np.int64]]:
    """A table of random values and visits whose first ``unvisited`` states were never seen."""
    states, labels = qlearning.labels(actions)
    rng = np.random.default_rng(seed)
    values = rng.normal(size=(len(states), len(labels)))
    visits = rng.integers(1, 9, size=values.shape)
    values[:unvisited] = 0.0
    visits[:unvisited] = 0
    return states, labels, values, visits


def greys(png: bytes) -> int:
    rgb = np.round(decode(png)[..., :3] * 255)
    return int(np.all(rgb == UNVISITED_GREY, axis=-1).sum())


def marks(figure: Figure, label: str) -> list[tuple[int, int]]:
    """The (action, state) cells a scatter layer of the figure marks."""
    for collection in figure.axes[0].collections:
        if collection.get_label() == label:
            return [(round(x), round(y)) for x, y in collection.get_offsets()]
    return []


@pytest.mark.parametrize("actions", ["behaviors", "directions"])
def test_the_qtable_picture_of_either_action_set_has_its_size(actions: str) -> None:
    states, labels, values, visits = random_table(actions)
    assert_picture(plots.qtable_png(states, labels, values, visits), QTABLE_SIZE[actions])


def test_the_qtable_picture_marks_each_greedy_action_and_greys_unvisited_states() -> None:
    states, labels, values, visits = random_table("behaviors", unvisited=10)
    values[20] = [0.5, 2.0, 2.0, -1.0]
    figure = plots.qtable_figure(states, labels, values, visits)
    greedy = marks(figure, "greedy action")
    assert greedy == [(int(np.argmax(values[s])), s) for s in range(10, len(states))]
    assert marks(figure, "tied for best") == [(1, 20), (2, 20)]
    shown = figure.axes[0].images[0].get_array()
    assert isinstance(shown, np.ma.MaskedArray)
    np.testing.assert_array_equal(shown.mask.all(axis=1), np.arange(len(states)) < 10)
    grey = greys(plots.qtable_png(states, labels, values, visits))
    all_seen = greys(plots.qtable_png(*random_table("behaviors")))
    assert grey > all_seen + 10 * 4 * 100  # ten rows of four cells, each far over 100 pixels


def test_the_qtable_picture_of_per_robot_tables_shows_their_visit_weighted_mean() -> None:
    states, labels = qlearning.labels("behaviors")
    values = np.zeros((2, len(states), len(labels)))
    visits = np.zeros(values.shape, dtype=np.int64)
    values[0, 0] = [3.0, 1.0, 0.0, 0.0]  # robot 0 tried two actions
    visits[0, 0] = [1, 5, 0, 0]
    values[1, 0] = [0.0, 4.0, 0.0, 0.0]  # robot 1 only the second, which it found better
    visits[1, 0] = [0, 5, 0, 0]
    figure = plots.qtable_figure(states, labels, values, visits)
    # mean: follow_gradient 3.0 (only robot 0 chose it), approach_cell (5 + 20) / 10 = 2.5
    assert marks(figure, "greedy action") == [(0, 0)]
    assert "mean of 2 robots' tables weighted by visits" in figure.get_suptitle()
