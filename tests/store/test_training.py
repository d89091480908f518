"""Jobs that train a network in the store: claimed only by a worker that trains; their
checkpoint kept under the lease, read back, and gone whichever way the job ends; their network
kept as a policy of the job's owner when it succeeds."""

from __future__ import annotations

from dataclasses import replace
from datetime import UTC, datetime, timedelta
from typing import Any

import pytest

from nanonav.store import JobStatus, JobStore, LeaseLost
from nanonav.store.policies import Network
from nanonav.store.queue import PRESENCE_WINDOW_S
from tests.store.test_queue import LEASE_S, outcome

TRAINS = {"seed": 1, "robots": {"policy": "ppo"}}
CURVE = [{"decisions": 10, "episodes": 2, "success_rate": 0.5, "return": 3.0}]


def test_only_a_worker_that_trains_claims_a_job_that_trains(store: JobStore) -> None:
    training = store.enqueue(TRAINS, robot_steps=10, episodes=1)
    plain = store.enqueue({"seed": 2}, robot_steps=10, episodes=1)
    assert training.trains and not plain.trains
    claimed = store.claim("plain", lease_s=LEASE_S)
    assert claimed is not None and claimed.job.id == plain.id
    assert store.claim("plain", lease_s=LEASE_S) is None
    trainer = store.claim("trainer", lease_s=LEASE_S, trains=True)
    assert trainer is not None and trainer.job.id == training.id


def test_the_census_counts_the_workers_that_train(store: JobStore) -> None:
    now = datetime.now(UTC)
    store.worker_seen("a", started_at=now, now=now)
    store.worker_seen("b", started_at=now, trains=True, now=now)
    store.worker_seen("c", started_at=now, ready=False, trains=True, now=now)
    census = store.census(seen_within_s=PRESENCE_WINDOW_S, now=now)
    assert (census.workers, census.trainers, census.preparing) == (2, 1, 1)
    later = now + timedelta(seconds=PRESENCE_WINDOW_S + 1)
    assert store.census(seen_within_s=PRESENCE_WINDOW_S, now=later).trainers == 0


def test_a_checkpoint_is_kept_under_the_lease_and_read_back(store: JobStore) -> None:
    job = store.enqueue(TRAINS, robot_steps=10, episodes=1)
    claim = store.claim("w", lease_s=LEASE_S, trains=True)
    assert claim is not None
    assert store.training.last(job.id) is None
    store.training.keep(job.id, claim.token, decisions=10, data=b"first", curve=CURVE)
    store.training.keep(job.id, claim.token, decisions=20, data=b"second", curve=CURVE * 2)
    kept = store.training.last(job.id)
    assert kept is not None
    assert (kept.decisions, kept.data, kept.curve) == (20, b"second", CURVE * 2)
    assert store.get(job.id).decisions == 20
    with pytest.raises(LeaseLost):
        store.training.keep(job.id, "another token", decisions=30, data=b"x", curve=[])
    assert store.get(job.id).training_curve == CURVE * 2  # the page draws the kept rows
    store.training.resumed(job.id, claim.token, 20, CURVE)
    assert store.get(job.id).resumed_from_decisions == 20
    assert store.get(job.id).training_curve == CURVE


def test_the_progress_writes_the_training_curve_as_it_grows(store: JobStore) -> None:
    job = store.enqueue(TRAINS, robot_steps=10, episodes=1)
    claim = store.claim("w", lease_s=LEASE_S, trains=True)
    assert claim is not None
    assert store.get(job.id).training_curve is None
    progress: dict[str, Any] = {"episode": 0, "episodes": 1, "fraction": 0.1, "lease_s": LEASE_S}
    store.report_progress(claim, decisions=10, curve=CURVE, **progress)
    assert store.get(job.id).training_curve == CURVE
    store.report_progress(claim, decisions=15, **progress)  # no new row: the rows stay
    assert (store.get(job.id).decisions, store.get(job.id).training_curve) == (15, CURVE)
    store.report_progress(claim, decisions=20, curve=CURVE * 2, **progress)
    assert store.get(job.id).training_curve == CURVE * 2


@pytest.mark.parametrize("end", ["finish", "fail", "cancel queued", "expire"])
def test_a_checkpoint_goes_when_its_job_ends(store: JobStore, end: str) -> None:
    job = store.enqueue(TRAINS, robot_steps=10, episodes=1)
    now = datetime.now(UTC)
    claim = store.claim("w", lease_s=LEASE_S, trains=True, now=now)
    assert claim is not None
    store.training.keep(job.id, claim.token, decisions=10, data=b"state", curve=CURVE)
    if end == "finish":
        store.finish(claim, outcome())
    elif end == "fail":
        store.fail(claim, "it failed")
    elif end == "cancel queued":
        store.release(claim)
        assert store.training.last(job.id) is not None  # kept for the next worker
        store.cancel(job.id)
    else:
        later = now + timedelta(seconds=2 * LEASE_S)
        assert store.recover_expired(max_attempts=1, now=later) == 1
        assert store.get(job.id).status is JobStatus.FAILED
    assert store.training.last(job.id) is None


def test_a_lease_run_out_queues_the_job_again_with_its_checkpoint(store: JobStore) -> None:
    job = store.enqueue(TRAINS, robot_steps=10, episodes=1)
    now = datetime.now(UTC)
    claim = store.claim("w", lease_s=LEASE_S, trains=True, now=now)
    assert claim is not None
    store.training.keep(job.id, claim.token, decisions=10, data=b"state", curve=CURVE)
    assert store.recover_expired(max_attempts=3, now=now + timedelta(seconds=2 * LEASE_S)) == 1
    assert store.get(job.id).status is JobStatus.QUEUED
    kept = store.training.last(job.id)
    assert kept is not None and kept.data == b"state"


def test_a_succeeded_job_keeps_its_network_as_a_policy_of_its_owner(store: JobStore) -> None:
    store.enqueue(TRAINS, robot_steps=10, episodes=1, owner="someone")
    claim = store.claim("w", lease_s=LEASE_S, trains=True)
    assert claim is not None
    network = Network("steering", ("none",), ["reading"], ["keep_heading", "tumble"], b"onnx")
    finished = store.finish(claim, replace(outcome(), trained=network))
    assert finished.trained_policy_id is not None
    policy = store.policies.get(finished.trained_policy_id)
    assert (policy.owner, policy.kind) == ("someone", "network")
    assert store.policies.table(policy.id)["model"].tobytes() == b"onnx"
    # deleted later, it is no longer named by the job that trained it
    store.policies.delete(policy.id)
    assert store.get(finished.id).trained_policy_id is None


def test_a_cancelled_training_keeps_no_network(store: JobStore) -> None:
    store.enqueue(TRAINS, robot_steps=10, episodes=1)
    claim = store.claim("w", lease_s=LEASE_S, trains=True)
    assert claim is not None
    network = Network("steering", ("none",), ["reading"], ["keep_heading", "tumble"], b"onnx")
    ended = store.finish(claim, replace(outcome(completed=False), trained=network))
    assert ended.status is JobStatus.CANCELLED and ended.trained_policy_id is None
    assert store.policies.page(limit=10, before_id=None).policies == []
