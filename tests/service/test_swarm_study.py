"""A study of the swarm shows the swarm's numbers in its answer, page, table and pictures; a
study of the paper's scenarios shows none of them, not even as empty columns."""

from __future__ import annotations

import csv
import io
import random
from typing import Any

from nanonav.engine.metrics import SWARM
from nanonav.store.queue import Outcome
from nanonav.studies.report import METRICS, PAPER_METRICS
from tests.conftest import Api
from tests.service.test_api import assert_problem

STUDY: dict[str, Any] = {
    "name": "swarm",
    "base": {"learning": {"episodes": 1, "max_steps": 30}},
    "grid": {"robots.count": [2, 4]},
    "seeds": [0, 1],
}


def finished_study(api: Api, keys: tuple[str, ...]) -> int:
    """A study whose four jobs succeeded reporting ``keys`` (random values in [0, 1])."""
    created = api.client.post("/studies", json=STUDY)
    assert created.status_code == 202, created.text
    rng = random.Random(0)
    for _ in range(4):
        claim = api.store.claim("test", lease_s=30)
        assert claim is not None
        metrics = {key: rng.random() for key in keys}
        outcome = Outcome(completed=True, metrics={"summary": metrics}, trajectory=None,
                          qtable=None, study_metrics=metrics)  # fmt: skip
        api.store.finish(claim, outcome)
    study_id: int = created.json()["id"]
    return study_id


def test_a_swarms_study_shows_the_swarms_numbers(api: Api) -> None:
    study_id = finished_study(api, METRICS)
    study = api.client.get(f"/studies/{study_id}").json()
    assert study["status"] == "succeeded" and study["metrics"] == list(METRICS)
    assert set(SWARM) <= set(study["links"]["plots"])
    assert set(study["points"][0]["metrics"]) == set(METRICS)
    header = next(csv.reader(io.StringIO(api.client.get(f"/studies/{study_id}/results.csv").text)))
    assert header[-len(METRICS) - 1 : -1] == list(METRICS)
    assert header[-1] == "wall_clock_duration_s", "the run's wall clock, after the results"
    page = api.client.get(f"/ui/studies/{study_id}").text
    for shown in ("treated fraction", "time to treat all", "never delivered", "bumps"):
        assert f"<th>{shown}</th>" in page, shown
    assert f"/studies/{study_id}/plots/treated_fraction.png" in page
    chart = api.client.get(f"/studies/{study_id}/plots/treated_fraction.png")
    assert chart.status_code == 200 and chart.content.startswith(b"\x89PNG")


def test_a_papers_study_shows_none_of_them(api: Api) -> None:
    study_id = finished_study(api, PAPER_METRICS)
    study = api.client.get(f"/studies/{study_id}").json()
    assert study["metrics"] == list(PAPER_METRICS)
    # its points learn (q_learning, the default): it has their policies picture
    assert set(study["links"]["plots"]) == {*PAPER_METRICS, "learning", "policies"}
    listed = api.client.get("/studies").json()["studies"][0]["links"]["plots"]
    assert listed == study["links"]["plots"]
    header = next(csv.reader(io.StringIO(api.client.get(f"/studies/{study_id}/results.csv").text)))
    assert not set(header) & set(SWARM)
    page = api.client.get(f"/ui/studies/{study_id}").text
    assert "treated fraction" not in page and "treated_fraction" not in page
    assert "bumps" not in page
    assert f"/studies/{study_id}/plots/success_rate.png" in page
    body = assert_problem(api.client.get(f"/studies/{study_id}/plots/treated_fraction.png"), 404)
    assert body["type"].endswith("no-metric")
    assert "reports treated_fraction" in body["detail"]
