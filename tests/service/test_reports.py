"""A running study's report is computed once per change of its jobs, not once per GET, and
is always the report its jobs give now."""

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
    return {key: answer[key] for key in ("metrics", "interval", "test", "points", "comparisons")}


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


def test_clients_that_miss_at_once_wait_for_one_computation() -> None:
    reports = Reports()
    started = threading.Barrier(8)
    calls = []

    def compute() -> dict[str, Any]:
        calls.append(1)
        return {"n": len(calls)}

    def get(_: int) -> dict[str, Any]:
        started.wait()
        return reports.get(("study", 1), compute)

    with ThreadPoolExecutor(max_workers=8) as pool:
        found = list(pool.map(get, range(8)))
    assert len(calls) == 1 and all(f == {"n": 1} for f in found)


def test_only_the_last_reports_are_kept() -> None:
    reports = Reports(size=2)
    for key in ("a", "b", "c"):
        reports.get(key, lambda key=key: {"key": key})
    assert reports.get("a", lambda: {"key": "again"}) == {"key": "again"}
    assert reports.get("c", lambda: {"key": "never"}) == {"key": "c"}
