"""The 3-D paths (Figure 3): obstacles to scale, robot ends over cells, subsets of many paths."""

from typing import Any

import numpy as np
import pytest
from mpl_toolkits.mplot3d import proj3d

from nanonav.engine import SimulationResult, simulate
from nanonav.pictures.figure import png
from nanonav.pictures.job.concentration import concentration_figure, concentration_png
from nanonav.pictures.job.learning import learning_png
from nanonav.pictures.job.trajectory import (
    COARSE_SPHERES_FROM,
    MAX_CELL_PATHS,
    MAX_ROBOT_PATHS,
    cells_with_paths,
    reached_cells,
    sphere_facets,
    sphere_mesh,
    trajectory_figure,
    trajectory_png,
)
from tests.pictures.data import offsets
from tests.pictures.job.results import (
    EXPECTED_SIZE,
    assert_picture,
    decode,
    made_trajectory,
    result_of,
    scenario,
)


def test_large_swarm_draws_a_subset_of_paths() -> None:
    big = simulate(
        scenario(
            seed=1,
            robots={"count": MAX_ROBOT_PATHS + 10, "policy": "gradient"},
            cells={"count": MAX_CELL_PATHS + 3},
            obstacles={"count": COARSE_SPHERES_FROM + 5, "radius": 0.5},
            learning={"episodes": 0, "max_steps": 60},
            evaluation={"worlds": 3},
        )
    )
    figure = trajectory_figure(big)
    colours = [line.get_color() for line in figure.axes[0].get_lines()]
    assert colours.count("tab:blue") == MAX_ROBOT_PATHS
    assert colours.count("tab:red") == MAX_CELL_PATHS
    assert f"paths of the first {MAX_ROBOT_PATHS} robots" in figure.axes[0].get_title()
    assert_picture(trajectory_png(big), EXPECTED_SIZE["trajectory"])
    assert_picture(learning_png(big), EXPECTED_SIZE["learning"])
    assert_picture(concentration_png(big), EXPECTED_SIZE["concentration"])


def test_obstacles_are_meshes_of_spheres_of_their_radius() -> None:
    centres = np.array([[1.0, 2.0, 3.0], [-4.0, 0.0, 5.0]])
    faces, grey = sphere_mesh(centres, 2.5)
    around, poles = sphere_facets(2)
    corners = faces.reshape(2, around * poles, 4, 3)
    radii = np.linalg.norm(corners - centres[:, None, None, :], axis=-1)
    assert radii == pytest.approx(np.full(radii.shape, 2.5))
    assert grey.shape == (2 * around * poles,) and 0.2 <= grey.min() < grey.max() <= 0.7
    assert sphere_facets(1000) == (6, 4)  # a thousand obstacles still draw quickly


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
    figure = trajectory_figure(result)
    image = decode(png(figure))
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
    ax: Any = trajectory_figure(swarm).axes[0]
    assert not ax.computed_zorder
    zorders = {c.get_label(): c.get_zorder() for c in ax.collections}
    assert zorders["robot end, reached"] > zorders["cell at the end"]


def test_a_robot_that_ends_on_its_cell_still_shows() -> None:
    robots = np.array([[[-10.0, 0.0, 0.0]], [[0.0, 0.0, 0.0]]])
    cells = np.zeros((2, 1, 3))
    result = result_of(made_trajectory(robots, cells, steps=[1], reached=[True]))
    figure = trajectory_figure(result)
    image = decode(png(figure))
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
    assert reached_cells(trajectory).tolist() == [0, 0, 0, 1, 0, 0, 0, 2, 0, 0]
    assert cells_with_paths(trajectory).tolist() == [0, 1, 3, 7]
    figure = trajectory_figure(result_of(trajectory))
    red = [line for line in figure.axes[0].get_lines() if line.get_color() == "tab:red"]
    assert len(red) == MAX_CELL_PATHS
    assert "paths of the 4 cells most reached drawn" in figure.axes[0].get_title()


def test_a_run_of_many_worlds_names_the_world_drawn_and_its_time_beside_their_mean() -> None:
    """The engine records the first evaluation world only: the titles say so, and give that
    world's time to reach beside the mean and range over all of them (Table 1's), so that a
    short first episode is not read as the run's."""
    many = simulate(
        scenario(
            preset="paper-single", seed=3, learning={"episodes": 0, "max_steps": 80},
            robots={"policy": "gradient"}, evaluation={"worlds": 5},
        )
    )  # fmt: skip
    steps = [float(w["total_steps"]) for w in many.worlds]
    figure = trajectory_figure(many)
    title = figure.axes[0].get_title()
    # below the paths, every world's time: the others as dots, the one drawn as a ring
    others, drawn = figure.axes[1].collections
    assert offsets(others)[:, 0].tolist() == steps[1:]
    assert offsets(drawn)[:, 0].tolist() == steps[:1]
    assert "each of the 5 worlds (steps)" in figure.axes[1].get_xlabel()
    assert "evaluation world 1 of 5" in title
    assert (
        f"time to reach: this world {steps[0]:,.4g}, mean of 5 worlds {np.mean(steps):,.4g} "
        f"({min(steps):,.4g}-{max(steps):,.4g}) steps"
    ) in title
    assert "evaluation world 1 of 5" in concentration_figure(many).get_suptitle()


def test_a_run_of_one_world_draws_its_evaluation_episode() -> None:
    one = simulate(
        scenario(
            preset="paper-single", seed=3, learning={"episodes": 0, "max_steps": 80},
            robots={"policy": "gradient"}, evaluation={"worlds": 1},
        )
    )  # fmt: skip
    figure = trajectory_figure(one)
    title = figure.axes[0].get_title()
    assert len(figure.axes) == 1  # no strip of worlds
    assert "evaluation episode" in title
    assert "mean of" not in title
