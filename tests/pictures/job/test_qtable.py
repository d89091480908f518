"""The Q-table picture: a row per state, the greedy actions marked, unvisited states grey."""

import numpy as np
import pytest
from matplotlib.collections import PathCollection
from matplotlib.figure import Figure
from numpy.typing import NDArray

from nanonav.engine import qlearning
from nanonav.pictures.job.qtable import GAP_DOT_MAX, GAP_DOT_MIN, qtable_figure, qtable_png
from tests.pictures.data import offsets
from tests.pictures.job.results import assert_picture, decode

# (width, height) in pixels: the figure grows with the table.
QTABLE_SIZE = {"behaviors": (830, 1500), "directions": (1120, 1230)}
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
            return [(round(x), round(y)) for x, y in offsets(collection)]
    return []


@pytest.mark.parametrize("actions", ["behaviors", "directions"])
def test_the_qtable_picture_of_either_action_set_has_its_size(actions: str) -> None:
    states, labels, values, visits = random_table(actions)
    assert_picture(qtable_png(states, labels, values, visits), QTABLE_SIZE[actions])


def test_the_qtable_picture_marks_each_greedy_action_and_greys_unvisited_states() -> None:
    states, labels, values, visits = random_table("behaviors", unvisited=10)
    values[20] = [0.5, 2.0, 2.0, -1.0]
    figure = qtable_figure(states, labels, values, visits)
    greedy = marks(figure, "greedy action")
    assert greedy == [(int(np.argmax(values[s])), s) for s in range(10, len(states))]
    assert marks(figure, "tied for best") == [(1, 20), (2, 20)]
    shown = figure.axes[0].images[0].get_array()
    assert isinstance(shown, np.ma.MaskedArray) and isinstance(shown.mask, np.ndarray)
    np.testing.assert_array_equal(shown.mask.all(axis=1), np.arange(len(states)) < 10)
    grey = greys(qtable_png(states, labels, values, visits))
    all_seen = greys(qtable_png(*random_table("behaviors")))
    assert grey > all_seen + 10 * 4 * 100  # ten rows of four cells, each far over 100 pixels


def test_the_qtable_picture_of_per_robot_tables_shows_their_visit_weighted_mean() -> None:
    states, labels = qlearning.labels("behaviors")
    values = np.zeros((2, len(states), len(labels)))
    visits = np.zeros(values.shape, dtype=np.int64)
    values[0, 0] = [3.0, 1.0, 0.0, 0.0]  # robot 0 tried two actions
    visits[0, 0] = [1, 5, 0, 0]
    values[1, 0] = [0.0, 4.0, 0.0, 0.0]  # robot 1 only the second, which it found better
    visits[1, 0] = [0, 5, 0, 0]
    figure = qtable_figure(states, labels, values, visits)
    # mean: follow_gradient 3.0 (only robot 0 chose it), approach_cell (5 + 20) / 10 = 2.5
    assert marks(figure, "greedy action") == [(0, 0)]
    assert "mean of 2 robots' tables weighted by visits" in figure.get_suptitle()


def test_each_greedy_dot_grows_with_its_action_gap_given_beside_the_visits() -> None:
    states = ["s0", "s1", "s2"]
    labels = ["a", "b", "c"]
    # gaps 0.1, 2.0 and 0 (a tie): a speck, the largest disc, the smallest dot
    values = np.array([[1.0, 0.9, 0.0], [-1.0, -3.0, -5.0], [0.5, 0.5, 0.0]])
    visits = np.ones((3, 3), dtype=np.int64)
    figure = qtable_figure(states, labels, values, visits)
    ax, right = figure.axes[0], figure.axes[1]
    (dots,) = [c for c in ax.collections if c.get_label() == "greedy action"]
    assert isinstance(dots, PathCollection)  # a scatter's
    sizes = dots.get_sizes()
    assert sizes[1] == pytest.approx(GAP_DOT_MAX)
    assert sizes[2] == pytest.approx(GAP_DOT_MIN)
    assert sizes[0] == pytest.approx(GAP_DOT_MIN + (GAP_DOT_MAX - GAP_DOT_MIN) * 0.05)
    texts = [t.get_text() for t in right.get_yticklabels()]
    assert texts == ["3  gap 0.1", "3  gap 2", "3  gap 0"]
    assert right.get_ylabel() == "visits, action gap"
