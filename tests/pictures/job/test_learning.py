"""The learning curve: the trials, their moving mean and the greedy evaluation."""

import typing

import numpy as np
import pytest
from matplotlib.container import ErrorbarContainer

from nanonav.engine import SimulationResult, simulate
from nanonav.pictures.job.learning import (
    MAX_SMOOTHING_WINDOW,
    learning_figure,
    learning_png,
    moving_mean,
    smoothing_window,
)
from nanonav.scenario import LATTICE_POLICIES, TRAINED_POLICIES, Policy
from tests.pictures.data import xdata, ydata
from tests.pictures.job.results import EXPECTED_SIZE, assert_picture, panel_titles, scenario


# the engine's policies (a network a job trains is drawn as the network it is evaluated as)
@pytest.mark.parametrize("policy", sorted(set(typing.get_args(Policy)) - TRAINED_POLICIES))
def test_every_policy_draws_its_learning_curve(policy: str) -> None:
    physics = "lattice" if policy in LATTICE_POLICIES else "active_brownian"
    run = simulate(
        scenario(
            seed=3,
            robots={"count": 3, "policy": policy},
            learning={"episodes": 2, "max_steps": 80},
            physics={"model": physics},
        )
    )
    assert_picture(learning_png(run), EXPECTED_SIZE["learning"])


def test_learning_curve_needs_at_least_one_episode() -> None:
    # Enough robots that the first report comes mid-way through the first episode.
    crowd = scenario(robots={"count": 2000, "policy": "random"}, learning={"episodes": 3})
    stopped = simulate(crowd, lambda _: False)
    assert stopped.episodes == [] and stopped.trajectory is None
    with pytest.raises(ValueError, match="no finished episode"):
        learning_png(stopped)


LEARNER_PANELS = [
    "steps per episode",
    "robots that reached a cell",
    "mean return per robot",
    "exploration rate",
]


def test_a_learner_shows_its_greedy_evaluation_as_a_mean_with_its_interval(
    swarm: SimulationResult,
) -> None:
    figure = learning_figure(swarm)
    assert panel_titles(figure) == LEARNER_PANELS
    steps, success, _, epsilon = figure.axes
    (bar,) = steps.containers
    assert isinstance(bar, ErrorbarContainer)
    x, y = bar.lines[0].get_data()
    assert isinstance(x, np.ndarray) and isinstance(y, np.ndarray)
    assert float(y[0]) == pytest.approx(swarm.summary["episode_steps"])
    spread = swarm.uncertainty["episode_steps"]
    assert spread["ci_high"] > spread["ci_low"]
    (segment,) = bar.lines[2][0].get_segments()
    assert segment[:, 1] == pytest.approx([spread["ci_low"], spread["ci_high"]])
    (rate,) = success.containers
    assert isinstance(rate, ErrorbarContainer)
    assert float(ydata(rate.lines[0])[0]) == pytest.approx(100 * swarm.summary["success_rate"])
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
    figure = learning_figure(run)
    assert panel_titles(figure) == LEARNER_PANELS[:3]
    assert not any(ax.containers for ax in figure.axes)
    ticks = [t.get_text() for ax in figure.axes for t in ax.get_xticklabels()]
    assert not any("evaluation" in t for t in ticks)
    title = figure.get_suptitle()
    assert title == "Gradient climbing does not learn: 6 training episodes, all trials alike"
    assert_picture(learning_png(run), EXPECTED_SIZE["learning"])


def test_a_baseline_without_training_draws_its_evaluation_worlds_as_trials() -> None:
    run = simulate(
        scenario(
            seed=4, robots={"count": 3, "policy": "rule"},
            learning={"episodes": 0, "max_steps": 80}, evaluation={"worlds": 5},
        )
    )  # fmt: skip
    figure = learning_figure(run)
    steps = figure.axes[0].get_lines()[-1]  # the moving mean over the raw line
    raw = figure.axes[0].get_lines()[0]
    assert xdata(raw).tolist() == [0, 1, 2, 3, 4]
    assert ydata(raw).tolist() == [w["episode_steps"] for w in run.worlds]
    assert steps.get_ydata() == pytest.approx(moving_mean(ydata(raw), 2))
    assert "5 evaluation worlds as trials" in figure.get_suptitle()
    assert figure.axes[-1].get_xlabel() == "evaluation world"


def test_the_moving_mean_spans_about_an_eighth_of_the_run() -> None:
    windows = [smoothing_window(n) for n in (1, 3, 4, 10, 20, 50, 200, 5000)]
    assert windows == [1, 1, 2, 2, 3, 7, 25, MAX_SMOOTHING_WINDOW]
    mean = moving_mean(np.array([2.0, 4.0, 6.0, 10.0, 0.0]), 3)
    assert mean == pytest.approx([2.0, 3.0, 4.0, 20 / 3, 16 / 3])


def test_a_short_run_gets_a_moving_mean_over_its_faint_raw_values() -> None:
    run = simulate(scenario(seed=6, robots={"count": 4}, learning={"episodes": 8, "max_steps": 80}))
    figure = learning_figure(run)
    raw, mean, *_ = figure.axes[0].get_lines()
    assert ydata(raw).tolist() == [e["steps"] for e in run.episodes]
    assert raw.get_alpha() == pytest.approx(0.3)
    assert mean.get_ydata() == pytest.approx(moving_mean(ydata(raw), 2))
    (legend,) = figure.legends
    assert "moving mean of 2" in [t.get_text() for t in legend.get_texts()]


def test_a_result_stored_without_its_trajectory_draws_the_same_learning_curve(
    swarm: SimulationResult,
) -> None:
    # what the service keeps of a job, read back without the (large) trajectory
    stored = SimulationResult.from_stored(swarm.to_dict(), {})
    assert stored.trajectory is None
    assert learning_png(stored) == learning_png(swarm)


def test_an_active_brownian_learner_counts_its_episodes_in_seconds() -> None:
    run = simulate(
        scenario(
            seed=3,
            robots={"count": 3, "policy": "q_learning"},
            learning={"episodes": 2},
            physics={"model": "active_brownian", "time_limit_s": 0.5},
            evaluation={"worlds": 2},
        )
    )
    figure = learning_figure(run)
    assert panel_titles(figure)[0] == "time per episode"
    seconds = figure.axes[0]
    assert seconds.get_ylabel() == "time (s)"
    dt = run.scenario.physics.step_s
    drawn = ydata(seconds.lines[0])
    assert list(drawn) == pytest.approx([e["steps"] * dt for e in run.episodes])
    (bar,) = seconds.containers
    assert isinstance(bar, ErrorbarContainer)
    assert float(ydata(bar.lines[0])[0]) == pytest.approx(run.summary["episode_steps"] * dt)
