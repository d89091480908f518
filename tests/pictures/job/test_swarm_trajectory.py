"""The 3-D paths of a swarm that delivers payloads: robots coloured by what they did and the
signal they read, treated cells apart; results without the swarm drawn as before."""

from dataclasses import replace
from typing import Any

import numpy as np
import pytest
from matplotlib.colors import to_rgba

from nanonav.engine import SimulationResult
from nanonav.pictures.figure import png
from nanonav.pictures.job.trajectory import (
    CARRYING_ORANGE,
    MESSAGE_PURPLE,
    swarm_view,
    trajectory_figure,
    trajectory_png,
)
from tests.pictures.job.results import (
    EXPECTED_SIZE,
    assert_picture,
    decode,
    made_trajectory,
    result_of,
)
from tests.pictures.job.swarm import treating_run


@pytest.fixture(scope="module")
def treating() -> SimulationResult:
    return treating_run()


def layers(figure: Any) -> dict[str, Any]:
    """The 3-D axes' scatter layers by label (the last of a label: a ring's coloured stroke)."""
    return {c.get_label(): c for c in figure.axes[0].collections if c.get_label()}


def without_swarm_colouring(result: SimulationResult) -> SimulationResult:
    assert result.trajectory is not None
    return replace(result, trajectory=replace(result.trajectory, delivered_to=None))


def test_a_swarms_paths_differ_from_the_same_paths_drawn_without_its_colouring(
    treating: SimulationResult,
) -> None:
    swarm = trajectory_png(treating)
    plain = trajectory_png(without_swarm_colouring(treating))
    assert_picture(swarm, EXPECTED_SIZE["trajectory"])
    assert_picture(plain, EXPECTED_SIZE["trajectory"])
    assert np.abs(decode(swarm) - decode(plain)).max() > 0.5
    figure = trajectory_figure(treating)
    drawn = layers(figure)
    assert len(drawn["treated cell"].get_offsets()) == 3  # every cell treated
    assert "cell to treat" not in drawn
    assert treating.trajectory is not None and treating.trajectory.delivered_to is not None
    delivered = int(np.count_nonzero(treating.trajectory.delivered_to >= 0))
    assert len(drawn["robot end, delivered"].get_offsets()) == delivered
    carrying = treating.scenario.robots.count - delivered
    assert len(drawn["robot end, still carrying"].get_offsets()) == carrying  # every end marked
    colourbar = figure.axes[1]
    assert colourbar.get_ylabel() == "net signal (a.u.)"
    assert "3 of 3 treated" in figure.get_suptitle()


def made_swarm(model: str, signals: list[float]) -> SimulationResult:
    """Three robots and two cells of capacity 1: robot 0 delivers to cell 0 at step 1 (treating
    it), robots 1 and 2 still carry their payloads at the end, having read ``signals``."""
    robots = np.array(
        [
            [[-10.0, 0.0, 0.0], [0.0, 10.0, 0.0], [0.0, -10.0, 0.0]],
            [[-5.0, 0.0, 0.0], [0.0, 12.0, 0.0], [0.0, -12.0, 0.0]],
            [[-5.0, 0.0, 0.0], [0.0, 14.0, 0.0], [0.0, -14.0, 0.0]],
        ]
    )
    cells = np.repeat(np.array([[[-5.0, 0.0, 0.0], [15.0, 15.0, 15.0]]]), 3, axis=0)
    trajectory = replace(
        made_trajectory(robots, cells, steps=[1, 2, 2], reached=[True, False, False]),
        cell_loads=np.array([[0, 0], [1, 0], [1, 0]]),
        delivered_to=np.array([0, -1, -1]),
        signals=np.array([[0.0, 0.0, 0.0], [0.0, 0.1, 0.0], [0.0, *signals]]),
    )
    return result_of(
        trajectory,
        robots={"count": 3, "policy": "rule", "exclusion": True},
        cells={"count": 2, "capacity": 1},
        communication={"model": model},
    )


def test_robots_still_carrying_are_coloured_by_the_signal_they_read_last() -> None:
    result = made_swarm("attractant_repellent", [0.8, -0.3])
    view = swarm_view(result)
    assert view is not None and view.signal is not None
    assert view.delivered.tolist() == [True, False, False]
    assert view.treated is not None and view.treated.tolist() == [True, False]
    assert view.signal[1:].tolist() == [0.8, -0.3]
    figure = trajectory_figure(result)
    carrying = layers(figure)["robot end, still carrying"]
    assert carrying.get_array().tolist() == [0.8, -0.3]
    low, high = carrying.norm.vmin, carrying.norm.vmax
    assert low == pytest.approx(-0.3) and high == pytest.approx(0.8)
    assert figure.axes[1].get_ylabel() == "net signal: attractant - repellent (a.u.)"
    assert len(layers(figure)["treated cell"].get_offsets()) == 1
    assert len(layers(figure)["cell to treat"].get_offsets()) == 1
    assert_picture(png(figure), EXPECTED_SIZE["trajectory"])


def test_with_broadcast_the_robots_still_carrying_show_whether_they_hold_a_message() -> None:
    figure = trajectory_figure(made_swarm("broadcast", [1.0, 0.0]))
    colours = [
        tuple(np.asarray(c.get_facecolor())[0])
        for c in figure.axes[0].collections
        if c.get_label() == "robot end, still carrying"
    ]
    assert colours == [to_rgba(MESSAGE_PURPLE), to_rgba(CARRYING_ORANGE)]
    assert len(figure.axes) == 1  # no colour bar: a message is held or not
    labels = [text.get_text() for text in figure.legends[0].get_texts()]
    assert "carrying, holds a message" in labels and "carrying, no message" in labels


def test_a_run_without_the_swarms_numbers_is_drawn_as_before(swarm: SimulationResult) -> None:
    assert swarm.trajectory is not None and swarm.trajectory.delivered_to is not None
    assert swarm_view(swarm) is None  # every episode records deliveries; the paper's is no swarm
    assert trajectory_png(swarm) == trajectory_png(without_swarm_colouring(swarm))
