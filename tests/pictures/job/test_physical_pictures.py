"""An active Brownian job's pictures speak its units: lengths in µm, the cancer cell drawn to
the scale of the obstacles, and a swarm that only takes up space (no payload to deliver) is
drawn and offered as the paper's, without the treatment picture."""

from dataclasses import replace

import numpy as np
import pytest
from mpl_toolkits.mplot3d import Axes3D
from mpl_toolkits.mplot3d.art3d import Poly3DCollection

from nanonav.engine import SimulationResult, simulate
from nanonav.pictures.job import render, render_all, treatment_drawn
from nanonav.pictures.job.concentration import concentration_figure
from nanonav.pictures.job.trajectory import trajectory_figure, trajectory_png
from nanonav.pictures.job.treatment import has_treatment, treatment_figure
from nanonav.scenario import preset_scenario
from tests.pictures.job.results import EXPECTED_SIZE, assert_picture, made_trajectory, result_of


@pytest.fixture(scope="module")
def microswimmers() -> SimulationResult:
    return simulate(
        preset_scenario(
            "tumour-microswimmers",
            seed=3,
            robots={"count": 4},
            physics={"time_limit_s": 0.6},
            learning={"episodes": 1},
            evaluation={"worlds": 1},
        )
    )


def test_active_brownian_lengths_are_in_micrometres(microswimmers: SimulationResult) -> None:
    ax = trajectory_figure(microswimmers).axes[0]
    assert isinstance(ax, Axes3D)
    assert [ax.get_xlabel(), ax.get_ylabel(), ax.get_zlabel()] == ["x (µm)", "y (µm)", "z (µm)"]
    labels = [a.get_ylabel() for a in concentration_figure(microswimmers).axes]
    assert any("(µm)" in label for label in labels)
    assert not any("um" in label.split() or "(um)" in label for label in labels)


def test_both_titles_say_who_reached_a_cell_within_the_same_seconds(
    microswimmers: SimulationResult,
) -> None:
    """The trajectory's title said "in 6000 steps" and the concentration's "within": both say
    "within" the episode's length, in seconds in the active Brownian physics."""
    trajectory = microswimmers.trajectory
    assert trajectory is not None
    seconds = trajectory.length * microswimmers.scenario.physics.step_s
    reached = int(np.count_nonzero(trajectory.reached))
    said = f"{reached} of 4 reached a cell within {seconds:.3g} s"
    for figure in (trajectory_figure(microswimmers), concentration_figure(microswimmers)):
        title = figure.axes[0].get_title() + figure.get_suptitle()
        assert said in title, title
        assert "steps" not in title.split(said)[1].split("\n")[0]


def cell_spheres(result: SimulationResult) -> list[Poly3DCollection]:
    return [
        c
        for c in trajectory_figure(result).axes[0].collections
        if isinstance(c, Poly3DCollection) and c.get_label() == "cell to scale"
    ]


def test_the_cancer_cell_is_drawn_to_scale(microswimmers: SimulationResult) -> None:
    assert microswimmers.trajectory is not None
    (sphere,) = cell_spheres(microswimmers)
    centre = microswimmers.trajectory.cells[-1, 0]
    # the faces' corners in data units (faces, corners, 3): matplotlib keeps no public copy
    faces = np.asarray(sphere._faces).reshape(-1, 3)
    reach = np.linalg.norm(faces - centre, axis=1)
    radius = microswimmers.scenario.physics.cell_radius_um
    assert radius == 7.5
    assert reach.max() == pytest.approx(radius, rel=1e-9)
    assert reach.min() > 0.9 * radius  # a sphere's surface, not a dot
    legend = [t.get_text() for t in trajectory_figure(microswimmers).legends[0].get_texts()]
    assert "cell, 7.5 µm radius to scale" in legend


def test_a_lattice_cell_stays_a_point(swarm: SimulationResult) -> None:
    assert cell_spheres(swarm) == []


def test_robots_that_only_take_up_space_deliver_no_payload(
    microswimmers: SimulationResult,
) -> None:
    scenario = microswimmers.scenario
    assert scenario.robots.exclusion and scenario.cells.capacity is None
    assert not treatment_drawn(scenario.model_dump(mode="json"))
    assert not has_treatment(microswimmers)
    assert "treatment" not in render_all(microswimmers)
    with pytest.raises(ValueError, match="no treatment to draw"):
        render(microswimmers, "treatment")
    figure = trajectory_figure(microswimmers)
    texts = [figure.axes[0].get_title(), figure.get_suptitle()]
    texts += [t.get_text() for t in figure.legends[0].get_texts()]
    assert not any("payload" in text or "carrying" in text for text in texts)
    assert "reached a cell" in figure.axes[0].get_title()
    assert_picture(trajectory_png(microswimmers), EXPECTED_SIZE["trajectory"])


def one_cell_treated() -> SimulationResult:
    """One robot and one cell that takes two payloads, the first delivered at step 2."""
    rows = 5
    cells = np.zeros((rows, 1, 3))
    trajectory = made_trajectory(np.ones((rows, 1, 3)), cells, steps=[rows - 1], reached=[True])
    loads = np.array([[0], [0], [1], [1], [1]])
    return result_of(
        replace(trajectory, cell_loads=loads, delivered_to=np.array([0])),
        robots={"count": 1},
        cells={"count": 1, "capacity": 2},
    )


def test_one_cell_is_a_cell_and_payloads_never_go_below_zero() -> None:
    figure = treatment_figure(one_cell_treated())
    title = figure.get_suptitle()
    assert "1 cancer cells" not in title and "the cancer cell" in title
    assert "1 payloads" not in title and "1 robots" not in title
    for ax in figure.axes:
        low, _ = ax.get_ylim()
        assert low == 0
        assert all(tick >= 0 for tick in ax.get_yticks() if low <= tick)
