"""Which swept key a study's pictures put on x, and that the learning picture draws curves."""

from __future__ import annotations

import io
from collections.abc import Mapping, Sequence

import numpy as np
import pytest
from matplotlib.figure import Figure
from matplotlib.image import imread
from matplotlib.lines import Line2D

from nanonav.pictures.figure import png as figure_png
from nanonav.pictures.study import (
    NO_EPISODES,
    NO_TRAINING,
    SECONDS_PANEL,
    axis_key,
    charts,
    learning_png,
    learning_points,
    metric_png,
    policies_png,
    training_png,
    training_points,
)
from nanonav.studies.report import METRICS, JobOutcome, learning_curve, report
from nanonav.studies.spec import StudySpec, point_values
from tests.pictures.data import xdata, ydata


def spec(grid: Mapping[str, Sequence[object]], compare: str | None) -> StudySpec:
    return StudySpec.model_validate({"grid": grid, "seeds": [0, 1, 2], "compare": compare})


def test_the_x_axis_is_the_first_swept_number_that_is_not_compared() -> None:
    policy = ["q_learning", "gradient"]
    assert axis_key(spec({"robots.policy": policy, "obstacles.count": [0, 5]}, "robots.policy")) \
        == "obstacles.count"  # fmt: skip
    assert axis_key(spec({"robots.count": [1, 2], "obstacles.count": [0, 5]}, "robots.count")) \
        == "obstacles.count"  # fmt: skip
    assert axis_key(spec({"robots.policy": policy}, "robots.policy")) is None
    assert axis_key(spec({"learning.shared_table": [True, False]}, None)) is None


def outcomes(study: StudySpec, with_curves: bool) -> list[JobOutcome]:
    rng = np.random.default_rng(0)
    found: list[JobOutcome] = []
    for point in range(len(point_values(study))):
        for seed in study.seed_list:
            curve = {"episode": [0.0, 1.0, 2.0], "steps": list(rng.uniform(50, 150, 3)),
                     "success_rate": [1.0, 1.0, 0.5], "mean_return": [3.0, 4.0, 5.0]}  # fmt: skip
            metrics = {m: float(rng.uniform(0, 1)) for m in METRICS}
            found.append(JobOutcome(len(found) + 1, point, seed, "succeeded", metrics,
                                    curve if with_curves else None))  # fmt: skip
    return found


def decode(png: bytes) -> np.ndarray:
    image: np.ndarray = imread(io.BytesIO(png), format="png")
    return image


def test_the_learning_picture_draws_each_points_mean_curve() -> None:
    study = spec({"robots.policy": ["q_learning", "gradient"]}, "robots.policy")
    drawn = decode(learning_png(study, point_values(study), outcomes(study, True)))
    empty = decode(learning_png(study, point_values(study), outcomes(study, False)))
    assert drawn.shape == empty.shape
    coloured = np.abs(drawn[..., 0] - drawn[..., 2]) > 0.3  # the blue and orange of the lines
    assert coloured.sum() > 5 * (np.abs(empty[..., 0] - empty[..., 2]) > 0.3).sum() + 100


def test_metric_pictures_draw_lines_or_bars() -> None:
    lines = spec({"robots.policy": ["q_learning", "gradient"], "obstacles.count": [0, 5]},
                 "robots.policy")  # fmt: skip
    bars = spec({"robots.policy": ["q_learning", "gradient"]}, "robots.policy")
    for study in (lines, bars):
        found = report(study, point_values(study), outcomes(study, False))
        image = decode(metric_png(study, found, "total_steps"))
        assert image.shape[:2] == (500, 1300) and image[..., :3].std() > 0.05  # with differences


class Received:
    """What the drawing functions were given: the series' labels, their x values (the labels of
    the bars' groups when x is not a number) and the axis label."""

    def __init__(self, monkeypatch: pytest.MonkeyPatch) -> None:
        self.labels: list[list[str]] = []
        self.xs: list[list[object]] = []
        self.x_labels: list[str | None] = []
        self.differences: list[list[str]] = []
        monkeypatch.setattr(charts, "metric_png", self.metric)
        monkeypatch.setattr(charts, "learning_png", self.learning)

    def metric(
        self,
        metric: str,
        series: Sequence[charts.Series],
        *,
        x_label: str | None,
        title: str | None = None,
        bounds: tuple[float, float] | None = None,
        differences: Sequence[charts.Difference] = (),
    ) -> bytes:
        self.labels.append([s.label for s in series])
        self.differences.append([d.label for d in differences])
        self.xs.append([x for s in series for x in s.x])
        self.x_labels.append(x_label)
        return b""

    def learning(
        self,
        panels: Mapping[str, Sequence[charts.Series]],
        *,
        title: str | None = None,
        **_: object,
    ) -> bytes:
        self.labels.extend([s.label for s in group] for group in panels.values())
        return b""


def test_series_are_labelled_by_readable_names_and_values(monkeypatch: pytest.MonkeyPatch) -> None:
    received = Received(monkeypatch)
    study = spec({"robots.policy": ["q_learning", "gradient"], "obstacles.count": [0, 5]},
                 "robots.policy")  # fmt: skip
    metric_png(study, report(study, point_values(study), outcomes(study, False)), "total_steps")
    assert received.labels == [["robots policy: q_learning", "robots policy: gradient"]]
    assert received.differences == [
        ["gradient vs q_learning\nobstacles count: 0", "gradient vs q_learning\nobstacles count: 5"]
    ]
    assert received.xs == [[0, 5, 0, 5]]
    assert received.x_labels == ["obstacles count"]
    learning_png(study, point_values(study), outcomes(study, True))
    points = [f"robots policy: {policy}, obstacles count: {count}"
              for policy in ("q_learning", "gradient") for count in (0, 5)]  # fmt: skip
    assert received.labels[1:] == [points] * 3  # one panel each: steps, success, return


def test_bars_are_labelled_by_readable_names_and_values(monkeypatch: pytest.MonkeyPatch) -> None:
    received = Received(monkeypatch)
    study = spec({"robots.policy": ["q_learning", "gradient"],
                  "learning.shared_table": [True, False]}, "robots.policy")  # fmt: skip
    metric_png(study, report(study, point_values(study), outcomes(study, False)), "success_rate")
    assert received.labels == [["robots policy: q_learning", "robots policy: gradient"]]
    assert received.xs == [["learning shared table: true", "learning shared table: false"] * 2]
    assert received.x_labels == [None]


def test_an_active_brownian_studys_learning_curves_count_seconds(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Each point's steps times its own dt_s, under a panel that says seconds."""
    drawn: dict[str, list[charts.Series]] = {}

    def learning(panels: Mapping[str, Sequence[charts.Series]], **_: object) -> bytes:
        drawn.update({k: list(v) for k, v in panels.items()})
        return b""

    monkeypatch.setattr(charts, "learning_png", learning)
    study = StudySpec.model_validate({
        "base": {"physics": {"model": "active_brownian", "time_limit_s": 1.0}},
        "grid": {"physics.dt_s": [0.01, 0.002]}, "seeds": [0, 1, 2],
    })  # fmt: skip
    jobs = outcomes(study, True)
    learning_png(study, point_values(study), jobs)
    assert list(drawn) == [SECONDS_PANEL, "success rate", "mean return per robot"]
    for point, dt in enumerate((0.01, 0.002)):
        steps = np.array([j.curve["steps"] for j in jobs if j.point == point and j.curve])
        assert drawn[SECONDS_PANEL][point].mean == pytest.approx(list(steps.mean(axis=0) * dt))
    lattice = spec({"robots.policy": ["q_learning", "gradient"]}, "robots.policy")
    learning_png(lattice, point_values(lattice), outcomes(lattice, True))
    assert "steps per episode" in drawn


def test_the_policies_picture_shows_each_learning_points_habits(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """A bar per most visited state of each point, split by the seeds' greedy actions; a real
    PNG with no table says it has no data."""
    states = np.array(["s0", "s1"], dtype=np.str_)
    actions = np.array(["a", "b"], dtype=np.str_)

    def table(best: int) -> dict[str, np.ndarray]:
        values = np.zeros((2, 2))
        values[:, best] = 1.0
        return {"states": states, "actions": actions, "values": values,
                "visits": np.array([[3, 1], [0, 0]])}  # fmt: skip

    study = spec({"robots.policy": ["q_learning", "gradient"]}, "robots.policy")
    assert learning_points(study) == [0]
    empty = decode(policies_png(study, point_values(study), {}))
    assert empty.shape[:2] == (262, 1000) and empty[..., :3].std() > 0.01
    rows: list[charts.HabitRow] = []

    def keep_rows(drawn: list[charts.HabitRow], **_: object) -> bytes:
        rows.extend(drawn)
        return b""

    monkeypatch.setattr(charts, "habits_png", keep_rows)
    policies_png(study, point_values(study), {0: [table(0), table(0), table(1)]})
    assert [r.label for r in rows] == [
        "robots policy: q_learning\ns0",
        "robots policy: q_learning\ns1",
    ]
    assert rows[0].shares == pytest.approx({"a": 2 / 3, "b": 1 / 3})
    assert rows[0].note == "100% of visits, mean gap 1, 3 seeds"


class Drawn:
    """The figures the charts save, kept (and still saved: the PNGs are real)."""

    def __init__(self, monkeypatch: pytest.MonkeyPatch) -> None:
        self.figures: list[Figure] = []
        saved = figure_png

        def keep(figure: Figure) -> bytes:
            self.figures.append(figure)
            return saved(figure)

        monkeypatch.setattr(charts, "png", keep)

    def texts(self) -> list[str]:
        return [t.get_text() for f in self.figures for ax in f.axes for t in ax.texts]


def untrained(study: StudySpec) -> list[JobOutcome]:
    """Every job succeeded, none trained: each keeps the curve of no episode, as a worker does."""
    empty = learning_curve({"summary": {}, "episodes": []})
    assert empty["episode"] == []
    # JobOutcome.curve's annotation leaves out the None a learning curve may hold
    return [
        JobOutcome(j.job_id, j.point, j.seed, j.status, j.metrics, empty)
        for j in outcomes(study, False)
    ]


def test_a_finished_study_without_training_episodes_says_so(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    drawn = Drawn(monkeypatch)
    study = spec({"robots.policy": ["gradient", "rule"]}, "robots.policy")
    image = decode(learning_png(study, point_values(study), untrained(study)))
    assert image[..., :3].std() > 0.01
    assert set(drawn.texts()) == {NO_EPISODES}
    queued = [JobOutcome(j.job_id, j.point, j.seed, "queued", None) for j in untrained(study)]
    learning_png(study, point_values(study), queued)
    assert set(drawn.texts()) == {NO_EPISODES, charts.NO_DATA}  # nothing has finished yet


def test_a_study_that_sweeps_only_its_compared_number_draws_a_line(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    counts: list[object] = [1, 2, 5, 10, 20]
    study = spec({"robots.count": counts}, "robots.count")
    assert axis_key(study) == "robots.count"
    received = Received(monkeypatch)
    found = report(study, point_values(study), outcomes(study, False))
    metric_png(study, found, "total_steps")
    assert received.labels == [["all seeds"]] and received.xs == [counts]
    assert received.x_labels == ["robots count"]
    monkeypatch.undo()
    drawn = Drawn(monkeypatch)
    decode(metric_png(study, found, "total_steps"))
    ax = drawn.figures[0].axes[0]  # the means (the paired differences beside them)
    assert not ax.patches  # no bars
    (line,) = [line for line in ax.get_lines() if line.get_linestyle() == "-"]  # not the caps
    assert np.asarray(line.get_xdata()).tolist() == counts


def test_a_shares_axis_runs_from_0_to_1_and_episodes_are_whole(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    drawn = Drawn(monkeypatch)
    study = spec({"robots.policy": ["q_learning", "gradient"]}, "robots.policy")
    jobs = [
        JobOutcome(j.job_id, j.point, j.seed, j.status, (j.metrics or {}) | {"success_rate": 1.0},
                   j.curve)
        for j in outcomes(study, True)
    ]  # fmt: skip
    found = report(study, point_values(study), jobs)
    decode(metric_png(study, found, "success_rate"))
    ax = drawn.figures[-1].axes[0]  # the means
    assert ax.get_ylim() == charts.SHARE_LIMITS
    caps = [c for c in ax.get_children() if isinstance(c, Line2D) and c.get_marker() == "_"]
    assert caps and not any(c.get_clip_on() for c in caps)  # a cap at 1 drawn whole
    decode(metric_png(study, found, "total_steps"))
    assert drawn.figures[-1].axes[0].get_ylim()[1] > 1.0  # only shares are kept to [0, 1]
    decode(learning_png(study, point_values(study), jobs))
    steps, success, _ = drawn.figures[-1].axes
    assert success.get_ylim() == charts.SHARE_LIMITS
    ticks = [t for t in steps.get_xticks() if steps.get_xlim()[0] <= t <= steps.get_xlim()[1]]
    assert ticks and all(float(t).is_integer() for t in ticks)


def test_a_policy_that_learns_nothing_is_a_level_on_the_learning_curves(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """The gradient rule's episodes are trials of one behaviour: one dashed level at the mean
    over its seeds of each seed's mean, not a curve; the learner keeps its curve."""
    drawn = Drawn(monkeypatch)
    study = spec({"robots.policy": ["q_learning", "gradient"]}, "robots.policy")
    jobs = outcomes(study, True)
    decode(learning_png(study, point_values(study), jobs))
    steps = drawn.figures[-1].axes[0]
    learner, rule = steps.get_lines()
    rule_seeds = [np.array(j.curve["steps"], dtype=float) for j in jobs
                  if j.point == 1 and j.curve is not None]  # fmt: skip
    level = float(np.mean([np.mean(c) for c in rule_seeds]))
    assert rule.get_linestyle() == "--"
    assert list(ydata(rule)) == pytest.approx([level, level])
    assert list(xdata(rule)) == [0.0, 2.0]  # across the episodes it ran
    learned = [np.array(j.curve["steps"], dtype=float) for j in jobs
               if j.point == 0 and j.curve is not None]  # fmt: skip
    assert list(ydata(learner)) == pytest.approx(np.mean(learned, axis=0).tolist())
    legend = [t.get_text() for t in drawn.figures[-1].legends[0].get_texts()]
    assert legend == ["robots policy: q_learning", "robots policy: gradient (fixed: its mean)"]


def test_the_training_picture_draws_each_learner_as_a_curve_and_each_rule_as_a_level(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """A study of gradient against ppo: ppo's training curve, the mean of its seeds' training
    success at each row's decisions, and gradient's evaluation success as a dashed level
    across the same decisions."""
    study = StudySpec.model_validate({
        "base": {"preset": "alonso-kirkegaard", "learning": {"decisions": 131_072}},
        "grid": {"robots.policy": ["gradient", "ppo"]}, "seeds": [0, 1],
        "compare": "robots.policy",
    })  # fmt: skip
    assert training_points(study) == [1]
    rows = [[0.2, 0.4], [0.4, 0.6]]  # the two seeds' training success at the two rows
    jobs = [JobOutcome(10 + seed, 0, seed, "succeeded", {"success_rate": 0.5 + 0.1 * seed})
            for seed in (0, 1)]  # fmt: skip
    for seed in (0, 1):
        document = {"summary": {}, "episodes": [], "training_curve": [
            {"decisions": d, "episodes": 8, "success_rate": s, "return": 1.0}
            for d, s in zip((65_536, 131_072), rows[seed], strict=True)
        ]}  # fmt: skip
        # JobOutcome.curve's annotation leaves out the None a learning curve may hold
        jobs.append(JobOutcome(20 + seed, 1, seed, "succeeded", {"success_rate": 0.1},
                               learning_curve(document)))  # fmt: skip
    drawn = Drawn(monkeypatch)
    image = decode(training_png(study, point_values(study), jobs))
    assert image[..., :3].std() > 0.01
    [figure] = drawn.figures
    [ax] = figure.axes
    lines = [line for line in ax.get_lines() if len(xdata(line)) > 1]
    curve = [line for line in lines if line.get_linestyle() != "--"]
    level = [line for line in lines if line.get_linestyle() == "--"]
    assert len(curve) == 1 and len(level) == 1
    assert list(xdata(curve[0])) == [65.536, 131.072]
    assert list(ydata(curve[0])) == pytest.approx([0.3, 0.5])
    assert list(ydata(level[0])) == pytest.approx([0.55, 0.55])  # gradient's evaluation
    assert ax.get_xlabel() == "decisions trained (thousands)"
    # a study none of whose learners has succeeded yet says so
    waiting = [j for j in jobs if j.point == 0]
    decode(training_png(study, point_values(study), waiting))
    assert NO_TRAINING in drawn.texts()
