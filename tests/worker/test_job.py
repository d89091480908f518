"""The worker's pieces in one process, over a real store (SQLite, PostgreSQL) and engine."""

from __future__ import annotations

import itertools
import math
import os
import signal
import threading
import time
from datetime import UTC, datetime
from typing import Any

import numpy as np
import pytest

from nanonav.engine import Progress
from nanonav.engine.observations import action_labels, observation_of
from nanonav.finite import finite
from nanonav.rl.evaluate import evaluate
from nanonav.scenario import Scenario
from nanonav.settings import Settings
from nanonav.store import Claim, JobRecord, JobStatus, JobStore
from tests.processes import sandbox_of
from tests.rl import models
from worker.health import healthy
from worker.job import Stop, Watch, heartbeat, run_job
from worker.loop import work

TINY: dict[str, Any] = {"robots": {"count": 2}, "learning": {"episodes": 1, "max_steps": 40}}


class Clock:
    def __init__(self) -> None:
        self.now = 100.0

    def __call__(self) -> float:
        return self.now


def claimed(store: JobStore, scenario: dict[str, Any] | None = None) -> Claim:
    store.enqueue(TINY if scenario is None else scenario, robot_steps=1, episodes=2)
    claim = store.claim("test", lease_s=30)
    assert claim is not None
    return claim


def settings_for(store: JobStore, **overrides: Any) -> Settings:
    url = store.engine.url.render_as_string(hide_password=False)
    return Settings(database_url=url, **overrides)


def test_progress_is_written_at_most_once_per_interval(store: JobStore) -> None:
    claim = claimed(store)
    clock = Clock()
    settings = settings_for(store, progress_interval_s=0.25)
    watch = Watch(store, claim, settings, threading.Event(), clock)
    assert watch(Progress(0, 2, 10, 40))
    assert store.get(claim.job.id).fraction == pytest.approx(10 / 80)
    clock.now += 0.1
    assert watch(Progress(0, 2, 30, 40))
    assert store.get(claim.job.id).fraction == pytest.approx(10 / 80)
    clock.now += 0.2
    assert watch(Progress(1, 2, 0, 40))
    job = store.get(claim.job.id)
    # approx in a tuple: mypy's strict equality cannot see that it compares by its __eq__
    assert (job.episode, job.fraction) == (  # type: ignore[comparison-overlap]
        1,
        pytest.approx(0.5),
    )


def test_a_cancel_request_stops_the_run_at_the_next_write(store: JobStore) -> None:
    claim = claimed(store)
    clock = Clock()
    watch = Watch(store, claim, settings_for(store), threading.Event(), clock)
    assert watch(Progress(0, 2, 1, 40))
    store.cancel(claim.job.id)
    clock.now += 1
    assert watch(Progress(0, 2, 2, 40)) is False
    assert watch.stop is Stop.CANCELLED


def test_the_time_limit_and_shutdown_stop_the_run(store: JobStore) -> None:
    claim = claimed(store)
    clock = Clock()
    shutdown = threading.Event()
    settings = settings_for(store, job_time_limit_s=5)
    watch = Watch(store, claim, settings, shutdown, clock)
    clock.now += 5.5
    assert watch(Progress(0, 2, 1, 40)) is False
    assert watch.stop is Stop.TIME_LIMIT
    other = Watch(store, claim, settings, shutdown, clock)
    shutdown.set()
    assert other(Progress(0, 2, 1, 40)) is False
    assert other.stop is Stop.SHUTDOWN


def test_a_lost_lease_stops_the_run(store: JobStore) -> None:
    claim = claimed(store)
    stale = Claim(job=claim.job, token="stolen", owner="x")
    watch = Watch(store, stale, settings_for(store), threading.Event(), Clock())
    assert watch(Progress(0, 2, 1, 40)) is False
    assert watch.stop is Stop.LEASE_LOST


def test_run_job_stores_a_finished_run(store: JobStore) -> None:
    claim = claimed(store)
    record = run_job(store, claim, settings_for(store), threading.Event())
    assert record is not None and record.status is JobStatus.SUCCEEDED
    assert set(store.trajectory(claim.job.id)) >= {"robots", "cells", "distance"}
    assert store.qtable(claim.job.id)["values"].ndim == 2
    assert store.plot(claim.job.id, "heatmap_all") is None  # drawn when first asked for


def test_run_job_fails_an_invalid_scenario_with_its_reason(store: JobStore) -> None:
    claim = claimed(store, {"robots": {"count": 0}})
    record = run_job(store, claim, settings_for(store), threading.Event())
    assert record is not None and record.status is JobStatus.FAILED
    assert record.error is not None and "robots.count" in record.error


def test_a_shutdown_gives_the_job_back(store: JobStore) -> None:
    long_run = {"learning": {"episodes": 200, "max_steps": 2000}, "robots": {"policy": "random"}}
    claim = claimed(store, long_run)
    shutdown = threading.Event()
    shutdown.set()
    assert run_job(store, claim, settings_for(store), shutdown) is None
    job = store.get(claim.job.id)
    assert (job.status, job.attempts) == (JobStatus.QUEUED, 0)


def test_work_runs_queued_jobs_then_returns(store: JobStore) -> None:
    ids = [store.enqueue({**TINY, "seed": seed}, robot_steps=1, episodes=2).id for seed in (1, 2)]
    settings = settings_for(store, poll_interval_s=0.01)
    assert work(settings, threading.Event(), max_jobs=2) == 2
    assert [store.get(i).status for i in ids] == [JobStatus.SUCCEEDED] * 2
    first, second = (store.metrics(i) for i in ids)
    assert first["scenario"]["seed"] == 1 and second["scenario"]["seed"] == 2
    assert store.trajectory(ids[0])["robots"].shape[1:] == (2, 3)


def test_finite_replaces_nan_and_infinity_with_none() -> None:
    document = {"a": [1.0, math.nan], "b": {"c": -math.inf}, "d": "x", "e": 2}
    assert finite(document) == {"a": [1.0, None], "b": {"c": None}, "d": "x", "e": 2}


def run_claimed(store: JobStore, scenario: dict[str, Any]) -> JobRecord:
    record = run_job(store, claimed(store, scenario), settings_for(store), threading.Event())
    assert record is not None
    return record


def test_a_policy_from_job_evaluates_the_named_table_without_learning(
    store: JobStore,
) -> None:
    source = run_claimed(store, TINY)
    assert source.status is JobStatus.SUCCEEDED
    evaluation = {**TINY, "seed": 5, "learning": {"episodes": 0, "max_steps": 40}}
    evaluated = run_claimed(store, {**evaluation, "policy_from": source.id})
    assert evaluated.status is JobStatus.SUCCEEDED, evaluated.error
    learned = store.qtable(source.id)["values"]
    assert np.any(learned != 0.0)
    np.testing.assert_array_equal(store.qtable(evaluated.id)["values"], learned)


def test_a_policy_from_job_whose_table_is_gone_or_unfit_fails_with_the_reason(
    store: JobStore,
) -> None:
    baseline = run_claimed(store, {**TINY, "robots": {"count": 2, "policy": "gradient"}})
    evaluation = {**TINY, "learning": {"episodes": 0, "max_steps": 40}}
    missing = run_claimed(store, {**evaluation, "policy_from": 999})
    assert missing.status is JobStatus.FAILED
    assert missing.error == "policy_from: there is no job 999"
    unfit = run_claimed(store, {**evaluation, "policy_from": baseline.id})
    assert unfit.status is JobStatus.FAILED
    assert (
        unfit.error == f"policy_from: job {baseline.id} learned no Q-table: only q_learning jobs do"
    )


def test_the_health_check_sees_a_worker_of_this_host_only(store: JobStore) -> None:
    settings = settings_for(store)
    assert not healthy(settings, host="box")
    store.worker_seen("box:12", started_at=datetime.now(UTC))
    assert healthy(settings, host="box")
    assert not healthy(settings, host="bo")
    assert not healthy(Settings(database_url="postgresql://nobody@127.0.0.1:1/none"), host="box")


def test_the_time_limit_stops_a_network_within_a_call_that_does_not_end(
    sqlite_store: JobStore,
) -> None:
    """The network's process hangs (stopped, as a runaway computation would hold it): the
    worker asks whether the run goes on while it waits, and fails the job at its time limit,
    long before the call's own limit."""
    scenario = Scenario()
    observation = list(observation_of(scenario).labels)
    actions = action_labels(scenario)
    network = sqlite_store.policies.add_network(
        action_set="behaviors", communication=("none",), observation=observation,
        actions=actions, model=models.mlp(len(observation), len(actions)),
    )  # fmt: skip
    long = {"robots": {"count": 50, "schedule": "simultaneous"},
            "learning": {"episodes": 0, "max_steps": 100_000}, "evaluation": {"worlds": 1},
            "policy_from": network.policy_from}  # fmt: skip
    tiny = {**long, "learning": {"episodes": 0, "max_steps": 5}, "policy_from": None}
    evaluate(Scenario.model_validate(tiny), lambda rows: np.zeros(len(rows), np.int64))
    claim = claimed(sqlite_store, long)  # the engine's step loaded above, before the clock
    settings = settings_for(sqlite_store, job_time_limit_s=3.0, network_call_limit_s=60.0)
    ran: dict[str, JobRecord | None] = {}
    thread = threading.Thread(
        target=lambda: ran.update(record=run_job(sqlite_store, claim, settings, threading.Event()))
    )
    started = time.monotonic()
    thread.start()
    while sqlite_store.get(claim.job.id).fraction == 0 and thread.is_alive():
        time.sleep(0.05)
    os.kill(sandbox_of(os.getpid()), signal.SIGSTOP)
    thread.join(timeout=60)
    record = ran["record"]
    assert record is not None and record.status is JobStatus.FAILED
    assert record.error == "stopped: the job ran past its time limit of 3 s"
    assert time.monotonic() - started < 15


def test_a_compile_does_not_starve_the_leases_heartbeat(sqlite_store: JobStore) -> None:
    """Numba compiling in the job's thread (one call that compiles three copies of the engine's
    field, ``fields.sample_many``, from its Python source into dispatchers of their own:
    nothing loaded from a cache) holds the interpreter in bursts only: the heartbeat renews
    the lease all along, never later than a lease after the last time."""
    from numba import njit

    from nanonav.engine import fields

    claim = claimed(sqlite_store)
    # renewed every third of a lease; the compiler holds the interpreter for up to about a
    # quarter of a second at a time (measured), so that a renewal comes late by that much, and
    # by more on a machine busy with other tests (1.4 s seen between renewals due 0.67 s apart,
    # and 3.04 s between renewals due 1 s apart): a lease of 6 s leaves a renewal 4 s to come
    settings = settings_for(sqlite_store, lease_s=6.0)
    renewed: list[float] = []
    renew = sqlite_store.renew

    def recorded(claim: Claim, *, lease_s: float, now: datetime | None = None) -> None:
        renewed.append(time.monotonic())
        renew(claim, lease_s=lease_s, now=now)

    sqlite_store.renew = recorded  # type: ignore[method-assign]
    sources, points = np.zeros(4), np.ones((3, 3))
    arguments = (fields.GAUSSIAN, sources, sources, sources, 1.0, 1.0, 0.1, points,
                 np.ones(3, np.bool_), np.zeros(3), np.zeros((3, 3)), *fields._NONE_TREATED,
                 0.0)  # fmt: skip
    options: dict[str, Any] = {"fastmath": fields.FASTMATH, "error_model": "numpy"}
    # about 4 s each on an idle machine: together longer than a lease
    first, second, third = (njit(**options)(fields.sample_many.py_func) for _ in range(3))

    def all_three(*arguments: Any) -> None:
        first(*arguments)
        second(*arguments)
        third(*arguments)

    started = time.monotonic()
    with heartbeat(sqlite_store, claim, settings):
        njit(**options)(all_three)(*arguments)  # all compiled here, now, in one call
        ended = time.monotonic()
    assert ended - started > settings.lease_s, "the compile was too quick to show anything"
    times = [started, *renewed, ended]
    assert max(b - a for a, b in itertools.pairwise(times)) < settings.lease_s
