"""A study's pictures of the swarm's numbers: listed and drawn once a job has them, refused for
a study whose jobs have none."""

from __future__ import annotations

import numpy as np
import pytest

from nanonav.pictures.study import EVERY_STUDYS_PICTURES, PICTURES, metric_png, pictures_of
from nanonav.studies.report import METRICS, PAPER_METRICS, SWARM_METRICS, JobOutcome, report
from nanonav.studies.spec import StudySpec, point_values
from tests.pictures.job.results import assert_picture

SPEC = StudySpec.model_validate(
    {"grid": {"robots.count": [20, 50, 100]}, "seeds": [0, 1, 2], "compare": None}
)


def jobs(swarm: bool) -> list[JobOutcome]:
    rng = np.random.default_rng(3)
    keys = METRICS if swarm else PAPER_METRICS
    return [
        JobOutcome(3 * point + seed + 1, point, seed, "succeeded",
                   {key: float(rng.uniform(0.1, 0.9)) for key in keys})
        for point in range(3)
        for seed in range(3)
    ]  # fmt: skip


def test_a_papers_study_has_no_picture_of_the_swarms_numbers() -> None:
    found = report(SPEC, point_values(SPEC), jobs(swarm=False))
    assert pictures_of(found) == EVERY_STUDYS_PICTURES == (*PAPER_METRICS, "learning")
    with pytest.raises(ValueError, match="no job of this study reports treated_fraction"):
        metric_png(SPEC, found, "treated_fraction")


def test_a_swarms_study_draws_each_of_the_swarms_numbers() -> None:
    found = report(SPEC, point_values(SPEC), jobs(swarm=True))
    # no policies (a picture of learning points), no training (of points that train)
    assert pictures_of(found) == PICTURES[:-2]
    assert pictures_of(found, learns=True) == PICTURES[:-1]
    assert pictures_of(found, learns=True, trains=True) == PICTURES
    drawn = {key: metric_png(SPEC, found, key) for key in SWARM_METRICS}
    for png in drawn.values():
        assert_picture(png, (800, 500))
    assert drawn["treated_fraction"] != drawn["bumps"]
