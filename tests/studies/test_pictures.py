"""Which swept key a study's pictures put on x, and that the learning picture draws curves."""

from __future__ import annotations

import io

import numpy as np
from matplotlib.image import imread

from nanonav.studies.pictures import axis_key, learning_png, metric_png
from nanonav.studies.report import METRICS, JobOutcome, report
from nanonav.studies.spec import StudySpec, point_values


def spec(grid: dict[str, list[object]], compare: str | None) -> StudySpec:
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
    found = []
    for point in range(len(point_values(study))):
        for seed in study.seed_list:
            curve = {"episode": [0.0, 1.0, 2.0], "steps": list(rng.uniform(50, 150, 3)),
                     "success_rate": [1.0, 1.0, 0.5], "mean_return": [3.0, 4.0, 5.0]}  # fmt: skip
            metrics = {m: float(rng.uniform(0, 1)) for m in METRICS}
            found.append(JobOutcome(len(found) + 1, point, seed, "succeeded", metrics,
                                    curve if with_curves else None))  # fmt: skip
    return found


def decode(png: bytes) -> np.ndarray:  # type: ignore[type-arg]
    image: np.ndarray = imread(io.BytesIO(png), format="png")  # type: ignore[type-arg]
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
        assert image.shape[:2] == (500, 800) and image[..., :3].std() > 0.05
