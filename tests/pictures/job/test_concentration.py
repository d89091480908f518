"""Concentration and distance (Figure 4): each robot only while it searches."""

from dataclasses import replace

import numpy as np
import pytest

from nanonav.engine import SimulationResult, Trajectory
from nanonav.pictures.figure import png
from nanonav.pictures.job.concentration import concentration_figure, searching_mask, searching_stats
from tests.pictures.data import xdata, ydata
from tests.pictures.job.results import EXPECTED_SIZE, assert_picture, made_trajectory, result_of


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
    searching = searching_mask(trajectory)
    assert searching.sum(axis=1).tolist() == [3, 3, 2, 2, 1]
    assert searching[:, 0].tolist() == [True, True, False, False, False]


def test_the_swarm_picture_follows_only_the_robots_still_searching() -> None:
    trajectory = drifting_cell_and_three_robots()
    stats = searching_stats(trajectory)
    assert stats.searching.tolist() == [3, 2, 2, 2, 2, 2]
    # Robot 0 sits 4 units behind the cell by the end; counted, it would pull the median to 10.
    assert stats.distance[1:, 1] == pytest.approx([11.0] * 5)
    assert stats.distance[1:, 0] == pytest.approx([10.5] * 5)
    assert stats.concentration[1:, 1] == pytest.approx([(1 / 11 + 1 / 13) / 2] * 5)
    figure = concentration_figure(result_of(trajectory, robots={"count": 3}))
    distance, _, count = figure.axes
    assert count.get_title() == "robots still searching (of 3)"
    assert ydata(count.get_lines()[0]).tolist() == [3, 2, 2, 2, 2, 2]
    assert distance.get_lines()[0].get_ydata() == pytest.approx(stats.distance[:, 1])
    assert "0 of 3 reached" not in figure.get_suptitle()
    assert "1 of 3 reached a cell within 5 steps" in figure.get_suptitle()
    assert_picture(png(figure), EXPECTED_SIZE["concentration"])


def test_one_robot_keeps_the_papers_twin_axes_up_to_its_reach(single: SimulationResult) -> None:
    trajectory = single.trajectory
    assert trajectory is not None and trajectory.reached[0]
    figure = concentration_figure(single)
    concentration, distance = figure.axes
    assert concentration.get_ylabel().startswith("biomarker concentration")
    assert distance.get_ylabel().startswith("distance to the nearest cell")
    (line,) = distance.get_lines()
    assert int(xdata(line)[-1]) == int(trajectory.robot_steps[0])
    assert f"reached a cell after {int(trajectory.robot_steps[0])} steps" in figure.get_suptitle()


def test_a_gaussian_field_felt_over_decades_is_drawn_on_a_log_axis() -> None:
    """The diffuse tumour's Gaussian field, felt far from its cells, spans decades and lay flat
    at 0 on a linear axis: a log axis then; a field felt within one decade stays linear."""
    trajectory = drifting_cell_and_three_robots()
    far = replace(trajectory, concentration=np.exp(-(trajectory.distance**2) / 18.0))
    near = replace(trajectory, concentration=1.0 + 0.1 * trajectory.distance)
    for felt, scale in ((far, "log"), (near, "linear")):
        figure = concentration_figure(result_of(felt, robots={"count": 3}))
        assert figure.axes[1].get_yscale() == scale
        assert ("log" in figure.axes[1].get_ylabel()) == (scale == "log")
