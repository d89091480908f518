"""A running study's report is computed once per change of its jobs, and at most about once a
second, not once per GET; with no minimum interval it is always the report its jobs give now."""

from __future__ import annotations

import random
import threading
from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from typing import Any

import httpx
import pytest

from nanonav.settings import Settings
from nanonav.store import JobStore, StudyStore
from nanonav.store.migrate import upgrade
from nanonav.store.queue import Outcome
from nanonav.studies.report import METRICS, report
from nanonav.studies.spec import StudySpec, point_values
from service.app import create_app
from service.reports import Reports
from service.routes.studies import _Loaded
from tests.conftest import SCRIPTED, serve

STUDY: dict[str, Any] = {
    "name": "polled",
    "base": {"learning": {"episodes": 1, "max_steps": 30}},
    "grid": {"robots.policy": ["q_learning", "gradient"]},
    "seeds": list(range(10)),
    "compare": "robots.policy",
}


@dataclass
class Polled:
    client: httpx.Client
    store: JobStore
    studies: StudyStore
    reports: Reports
    study: int


@pytest.fixture
def polled(sqlite_url: str) -> Iterator[Polled]:
    upgrade(sqlite_url)
    app = create_app(Settings(database_url=sqlite_url))
    store = JobStore.from_url(sqlite_url)
    app.state.reports = Reports(min_interval_s=0.0)  # every change shows at once
    with serve(app) as url, httpx.Client(base_url=url, headers=SCRIPTED, timeout=30) as client:
        study = client.post("/studies", json=STUDY).json()["id"]
        yield Polled(client, store, StudyStore(store.engine), app.state.reports, study)
    store.close()


def finish(polled: Polled, rng: random.Random, count: int) -> None:
    for _ in range(count):
        claim = polled.store.claim("test", lease_s=30)
        assert claim is not None
        metrics = {key: rng.random() for key in METRICS}
        outcome = Outcome(completed=True, metrics={"summary": metrics}, trajectory=None,
                          qtable=None, study_metrics=metrics)  # fmt: skip
        polled.store.finish(claim, outcome)


def fresh_report(polled: Polled) -> dict[str, Any]:
    """The report computed from every job now, with no cache."""
    record = polled.studies.get(polled.study)
    loaded = _Loaded.of(polled.studies, record)
    return report(StudySpec.model_validate(record.spec), point_values(loaded.spec), loaded.outcomes)


def statistics(answer: dict[str, Any]) -> dict[str, Any]:
    return {
        key: answer[key]
        for key in (
            "metrics",
            "interval",
            "test",
            "adjustment",
            "resolution",
            "points",
            "comparisons",
        )
    }


def test_polling_an_unchanged_study_computes_its_report_once(polled: Polled) -> None:
    finish(polled, random.Random(1), 8)
    before = polled.reports.computed
    answers = [polled.client.get(f"/studies/{polled.study}").json() for _ in range(20)]
    assert polled.reports.computed == before + 1
    assert all(answer == answers[0] for answer in answers)
    assert statistics(answers[0]) == fresh_report(polled)
    assert answers[0]["jobs"]["succeeded"] == 8 and answers[0]["status"] == "running"


def test_each_finished_job_shows_in_the_next_answer(polled: Polled) -> None:
    rng = random.Random(2)
    seen = []
    for _ in range(5):
        finish(polled, rng, 1)
        answer = polled.client.get(f"/studies/{polled.study}").json()
        assert statistics(answer) == fresh_report(polled)
        seen.append(answer["jobs"]["succeeded"])
    assert seen == [1, 2, 3, 4, 5]
    # a job that starts changes the counts of its point, and so the report
    claim = polled.store.claim("test", lease_s=30)
    assert claim is not None
    answer = polled.client.get(f"/studies/{polled.study}").json()
    assert answer["jobs"]["running"] == 1 and statistics(answer) == fresh_report(polled)


def test_the_finished_study_answers_as_before_and_keeps_its_report(polled: Polled) -> None:
    finish(polled, random.Random(3), 20)
    answer = polled.client.get(f"/studies/{polled.study}").json()
    assert answer["status"] == "succeeded" and answer["progress"] == 1.0
    assert answer["finished_at"] is not None
    assert statistics(answer) == fresh_report(polled)
    assert polled.studies.get(polled.study).report == statistics(answer)


def test_clients_that_miss_a_first_report_at_once_wait_for_one_computation() -> None:
    reports = Reports()
    started = threading.Barrier(8)
    calls = []

    def compute() -> dict[str, Any]:
        calls.append(1)
        return {"n": len(calls)}

    def get(_: int) -> dict[str, Any]:
        started.wait()
        return reports.get(1, ("v", 1), compute)

    with ThreadPoolExecutor(max_workers=8) as pool:
        found = list(pool.map(get, range(8)))
    assert len(calls) == 1 and all(f == {"n": 1} for f in found)


class Clock:
    def __init__(self) -> None:
        self.now = 100.0

    def __call__(self) -> float:
        return self.now


def test_a_changing_study_is_computed_again_at_most_once_per_interval() -> None:
    clock = Clock()
    reports = Reports(min_interval_s=1.0, clock=clock)
    assert reports.get(1, "v1", lambda: {"v": 1}) == {"v": 1}
    clock.now += 0.5
    assert reports.get(1, "v2", lambda: {"v": 2}) == {"v": 1}  # too soon: the last one
    assert reports.get(1, "v2", lambda: {"v": 2}, exact=True) == {"v": 2}  # a finished study
    clock.now += 0.2
    assert reports.get(1, "v3", lambda: {"v": 3}) == {"v": 2}
    clock.now += 1.0
    assert reports.get(1, "v3", lambda: {"v": 3}) == {"v": 3}
    assert reports.get(1, "v3", lambda: {"v": -1}) == {"v": 3}
    assert reports.computed == 3


def test_while_one_request_computes_a_new_report_the_others_get_the_last() -> None:
    reports = Reports(min_interval_s=0.0)
    reports.get(1, "v1", lambda: {"v": 1})
    inside, release = threading.Event(), threading.Event()

    def slow() -> dict[str, Any]:
        inside.set()
        release.wait(10)
        return {"v": 2}

    with ThreadPoolExecutor(max_workers=1) as pool:
        computing = pool.submit(reports.get, 1, "v2", slow)
        assert inside.wait(10)
        assert reports.get(1, "v2", lambda: {"v": -1}) == {"v": 1}
        release.set()
        assert computing.result(10) == {"v": 2}
    assert reports.get(1, "v2", lambda: {"v": -1}) == {"v": 2}


def test_only_the_last_studies_are_kept() -> None:
    reports = Reports(size=2, min_interval_s=0.0)
    for study in ("a", "b", "c"):

        def compute(study: str = study) -> dict[str, Any]:
            return {"study": study}

        reports.get(study, 1, compute)
    assert reports.get("a", 1, lambda: {"study": "again"}) == {"study": "again"}
    assert reports.get("c", 1, lambda: {"study": "never"}) == {"study": "c"}
