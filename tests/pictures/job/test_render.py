"""Every picture by name: each PNG decodes, has the promised size and shows something."""

import pytest

from nanonav.engine import Progress, SimulationResult, simulate
from nanonav.pictures.job import OPTIONAL_PICTURES, PICTURE_NAMES, render, render_all
from nanonav.pictures.job.concentration import concentration_png
from nanonav.pictures.job.heatmap import heatmap_png
from nanonav.pictures.job.learning import learning_figure, learning_png
from nanonav.pictures.job.trajectory import trajectory_png
from tests.pictures.job.results import EXPECTED_SIZE, assert_picture, scenario


def test_render_all_gives_every_named_picture_at_its_size(swarm: SimulationResult) -> None:
    pictures = render_all(swarm)
    assert tuple(pictures) == tuple(n for n in PICTURE_NAMES if n != "treatment")  # no swarm's
    for name, png in pictures.items():
        assert_picture(png, EXPECTED_SIZE[name])


def test_a_policy_that_learns_no_table_has_every_picture_but_the_qtable() -> None:
    walkers = simulate(
        scenario(seed=2, robots={"count": 3, "policy": "random"},
                 learning={"episodes": 1, "max_steps": 60}, evaluation={"worlds": 2})
    )  # fmt: skip
    assert tuple(render_all(walkers)) == tuple(
        n for n in PICTURE_NAMES if n not in OPTIONAL_PICTURES
    )
    with pytest.raises(ValueError, match="'random' policy learns no Q-table"):
        render(walkers, "qtable")


def test_single_robot_pictures_render_at_their_size(single: SimulationResult) -> None:
    assert_picture(trajectory_png(single), EXPECTED_SIZE["trajectory"])
    assert_picture(concentration_png(single), EXPECTED_SIZE["concentration"])
    assert_picture(learning_png(single), EXPECTED_SIZE["learning"])


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
    assert_picture(learning_png(stopped), EXPECTED_SIZE["learning"])
    assert not any(ax.containers for ax in learning_figure(stopped).axes)  # no evaluation
    for draw in (trajectory_png, concentration_png, heatmap_png):
        with pytest.raises(ValueError, match="no evaluation episode"):
            draw(stopped)
    with pytest.raises(ValueError, match="no evaluation episode"):
        render_all(stopped)


def test_a_stored_result_draws_the_same_pictures_as_the_live_one(swarm: SimulationResult) -> None:
    stored = SimulationResult.from_stored(swarm.to_dict(), swarm.arrays())
    assert stored.trajectory is not None and swarm.trajectory is not None
    assert stored.trajectory.stride == swarm.trajectory.stride
    for name in ("heatmap_xy", "trajectory", "learning"):
        assert render(stored, name) == render(swarm, name)


def test_render_names_every_picture_and_refuses_others(single: SimulationResult) -> None:
    for name in (n for n in PICTURE_NAMES if n != "treatment"):  # test_treatment draws that one
        assert_picture(render(single, name), EXPECTED_SIZE[name])
    with pytest.raises(ValueError, match="no picture 'heatmap_xx'"):
        render(single, "heatmap_xx")
