"""End to end: networks trained in jobs by real ``python -m worker --train`` processes. A
worker without ``--train`` never claims such a job, which says what it waits for; a ``ppo``
job trains, succeeds, keeps its network as a policy that a second job evaluates; a training
job whose worker is SIGKILLed after its first checkpoint is resumed from it by another worker
and leaves no checkpoint behind; a cancel during training ends it within seconds; a study sets a
rule against a learner, paired by seed, in one request."""

from __future__ import annotations

import signal
import time
from collections.abc import Callable
from typing import Any

import pytest
from sqlalchemy import func, select

from nanonav.store import JobStore
from nanonav.store.models import JobCheckpoint
from tests.conftest import Api
from tests.e2e.test_jobs import decode_png, finished, submit, wait_for
from tests.e2e.test_studies import wait_study
from tests.processes import FIRST_JOB_S, Worker

pytestmark = pytest.mark.timeout(420)

ROLLOUT = 1024 * 64  # decisions of one rollout of the trainer's default worlds


def training(policy: str = "ppo", **learning: int) -> dict[str, Any]:
    return {
        "preset": "alonso-kirkegaard",
        "seed": 11,
        "robots": {"policy": policy},
        "learning": {"decisions": 2 * ROLLOUT, **learning},
        "evaluation": {"worlds": 4},
    }


def checkpoints(api: Api) -> int:
    store = JobStore.from_url(api.database_url)
    try:
        with store.engine.connect() as connection:
            return int(connection.execute(select(func.count()).select_from(JobCheckpoint)).one()[0])
    finally:
        store.close()


def test_a_ppo_job_trains_in_a_worker_that_trains_and_its_network_evaluates_in_another_job(
    api: Api, start_worker: Callable[..., Worker]
) -> None:
    plain = start_worker()
    plain.wait_ready()
    job_id = submit(api, training())
    rule = {"preset": "alonso-kirkegaard", "seed": 11, "robots": {"policy": "gradient"},
            "evaluation": {"worlds": 4}}  # fmt: skip
    rule_id = submit(api, rule)
    ran, _ = wait_for(api, rule_id, finished, FIRST_JOB_S)
    assert ran["status"] == "succeeded", ran
    job = api.client.get(f"/jobs/{job_id}").json()
    # the worker that does not train ran the job after it and left this one alone
    assert job["status"] == "queued" and job["attempts"] == 0
    assert "nanonav worker --train" in job["waiting_for"]
    page = api.client.get(f"/ui/jobs/{job_id}").text
    assert 'id="waiting-for"' in page

    start_worker("--train")
    running, _ = wait_for(api, job_id, lambda j: j["status"] != "queued", FIRST_JOB_S)
    assert running["waiting_for"] is None
    job, _ = wait_for(api, job_id, finished, FIRST_JOB_S)
    assert job["status"] == "succeeded", job
    assert job["progress"]["training_decisions"] == 2 * ROLLOUT
    assert job["resumed_from_decisions"] is None
    trained = job["trained_policy"]
    assert trained is not None and trained.startswith("policy-")
    assert job["links"]["trained_policy"] == f"/policies/{trained[7:]}"

    metrics = api.client.get(f"/jobs/{job_id}/metrics").json()
    curve = metrics["training_curve"]
    assert [row["decisions"] for row in curve] == [ROLLOUT, 2 * ROLLOUT]
    assert job["progress"]["training_curve"] == curve  # what the page drew, whole at the end
    assert sum(row["episodes"] for row in curve) > 0
    assert metrics["training"]["decisions"] == 2 * ROLLOUT
    assert metrics["training"]["decisions_per_s"] > 0
    assert metrics["summary"]["worlds"] == 4

    for name, link in job["links"]["plots"].items():  # the pictures of a network's run
        picture = api.client.get(link)
        assert picture.status_code == 200, (name, picture.text)
        decode_png(picture.content)
    page = api.client.get(f"/ui/jobs/{job_id}").text
    assert 'id="trained-policy"' in page and "trained for 131,072 decisions" in page
    policy = api.client.get(f"/policies/{trained[7:]}").json()
    assert policy["kind"] == "network"
    evaluated = {"preset": "alonso-kirkegaard", "seed": 11, "policy_from": trained,
                 "learning": {"episodes": 0}, "evaluation": {"worlds": 4}}  # fmt: skip
    again_id = submit(api, evaluated)
    again, _ = wait_for(api, again_id, finished, FIRST_JOB_S)
    assert again["status"] == "succeeded", again
    # the same network on the same evaluation worlds decides the same
    again_metrics = api.client.get(f"/jobs/{again_id}/metrics").json()
    assert again_metrics["summary"]["success_rate"] == metrics["summary"]["success_rate"]
    assert checkpoints(api) == 0


def test_a_killed_training_worker_is_resumed_from_its_checkpoint_and_a_cancel_ends_training(
    api: Api, start_worker: Callable[..., Worker]
) -> None:
    # the killed worker's lease is short, so its job is taken up again soon; long enough, and
    # the second worker's the default, that neither lapses while a loaded machine trains
    fast = {"NANONAV_LEASE_S": "6", "NANONAV_PROGRESS_INTERVAL_S": "0.2"}
    first = start_worker("--train", **fast)
    job_id = submit(api, training("recurrent_ppo", decisions=5 * ROLLOUT,
                                  checkpoint_decisions=ROLLOUT))  # fmt: skip
    wait_for(api, job_id, lambda j: checkpoints(api) > 0, FIRST_JOB_S)
    first.process.send_signal(signal.SIGKILL)
    first.process.wait()
    start_worker("--train", NANONAV_PROGRESS_INTERVAL_S="0.2")
    job, _ = wait_for(api, job_id, finished, 2 * FIRST_JOB_S)
    assert job["status"] == "succeeded", job
    assert job["attempts"] == 2
    assert job["resumed_from_decisions"] >= ROLLOUT
    metrics = api.client.get(f"/jobs/{job_id}/metrics").json()
    assert metrics["training"]["resumed_from_decisions"] == job["resumed_from_decisions"]
    rows = [row["decisions"] for row in metrics["training_curve"]]
    assert rows == sorted(rows) and rows[-1] == 5 * ROLLOUT and rows[0] <= ROLLOUT
    assert checkpoints(api) == 0

    long_id = submit(api, training(decisions=200 * ROLLOUT, checkpoint_decisions=ROLLOUT))
    wait_for(api, long_id, lambda j: (j["progress"]["decisions"] or 0) >= ROLLOUT, FIRST_JOB_S)
    asked = time.monotonic()
    assert api.client.post(f"/jobs/{long_id}/cancel").status_code == 200
    cancelled, _ = wait_for(api, long_id, finished, 30)
    assert cancelled["status"] == "cancelled"
    assert time.monotonic() - asked < 5
    assert cancelled["trained_policy"] is None
    assert checkpoints(api) == 0


def test_a_study_compares_a_rule_with_a_learner_trained_in_its_jobs(
    api: Api, start_worker: Callable[..., Worker]
) -> None:
    start_worker("--train")
    study = {
        "name": "gradient against ppo",
        # one base for both: the rule leaves learning.decisions unused
        "base": {"preset": "alonso-kirkegaard", "learning": {"decisions": ROLLOUT},
                 "evaluation": {"worlds": 4}},
        "grid": {"robots.policy": ["gradient", "ppo"]},
        "seeds": [1, 2, 3],
        "compare": "robots.policy",
    }  # fmt: skip
    created = api.client.post("/studies", json=study)
    assert created.status_code == 202, created.text
    done = wait_study(api, created.json()["id"], 3 * FIRST_JOB_S)
    assert done["status"] == "succeeded", done["jobs"]
    [comparison] = done["comparisons"]
    assert (comparison["method"], comparison["baseline"]) == ("ppo", "gradient")
    success = comparison["metrics"]["success_rate"]
    assert success["n"] == 3 and "p_holm" in success
    jobs = api.client.get("/jobs", params={"study": done["id"], "limit": 10}).json()["jobs"]
    learners = [job for job in jobs if job["scenario"]["robots"]["policy"] == "ppo"]
    assert len(learners) == 3 and all(job["trained_policy"] for job in learners)
    # paired by seed: each seed's learner and rule met the same evaluation worlds
    assert sorted(job["scenario"]["seed"] for job in learners) == [1, 2, 3]
    # the learner's training curve beside the rule's level, in one picture
    training = done["links"]["plots"]["training"]
    picture = api.client.get(training)
    assert picture.status_code == 200, picture.text
    decode_png(picture.content)
    page = api.client.get(f"/ui/studies/{done['id']}").text
    assert f"/studies/{done['id']}/plots/training.png" in page
