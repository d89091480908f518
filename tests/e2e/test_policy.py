"""End to end: a table learned by one job, evaluated by another in a different field, and the
same table sent as a policy, through the API and a real ``python -m worker`` process."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import pytest

from tests.conftest import Api
from tests.e2e.test_jobs import decode_png, finished, submit, wait_for
from tests.processes import FIRST_JOB_S, Worker

TRAIN: dict[str, Any] = {
    "seed": 3,
    "robots": {"count": 2},
    "learning": {"episodes": 8, "max_steps": 150, "actions": "directions"},
}
# The same swarm in another field model, with no training: only the table it starts from differs.
EVALUATE: dict[str, Any] = {
    "seed": 11,
    "robots": {"count": 2},
    "biomarker": {"model": "diffusion"},
    "learning": {"episodes": 0, "max_steps": 150, "actions": "directions"},
}
TIMINGS = ("duration_s",)

pytestmark = pytest.mark.timeout(240)


def run(api: Api, scenario: dict[str, Any], timeout: float = 60) -> int:
    job_id = submit(api, scenario)
    job, _ = wait_for(api, job_id, finished, timeout)
    assert job["status"] == "succeeded", job
    return job_id


def summary(api: Api, job_id: int) -> dict[str, Any]:
    found: dict[str, Any] = api.client.get(f"/jobs/{job_id}/metrics").json()["summary"]
    return {k: v for k, v in found.items() if k not in TIMINGS}


def test_a_learned_table_is_evaluated_in_another_field_without_learning(
    api: Api, start_worker: Callable[..., Worker]
) -> None:
    start_worker()
    trained = run(api, TRAIN, FIRST_JOB_S)
    source = api.client.get(f"/jobs/{trained}/qtable").json()
    assert len(source["actions"]) == 26 and np.any(np.asarray(source["values"]) != 0.0)

    evaluated = run(api, {**EVALUATE, "policy_from": trained})
    untrained = run(api, EVALUATE)

    table = api.client.get(f"/jobs/{evaluated}/qtable").json()
    assert table["values"] == source["values"]  # the evaluation does not learn
    learned = [i for i, row in enumerate(source["values"]) if any(row)]
    assert learned
    assert [table["greedy"][i]["action"] for i in learned] == [
        source["greedy"][i]["action"] for i in learned
    ]
    # an untrained learner's table is all zeros: it offers none
    assert api.client.get(f"/jobs/{untrained}/qtable").status_code == 404
    assert api.client.get(f"/jobs/{untrained}").json()["links"]["qtable"] is None
    assert summary(api, evaluated) != summary(api, untrained)
    decode_png(api.client.get(f"/jobs/{evaluated}/plots/qtable.png").content)


def test_a_policy_sent_with_a_jobs_table_evaluates_exactly_as_that_jobs_table(
    api: Api, start_worker: Callable[..., Worker]
) -> None:
    """The table a job learned, sent back as a policy (as a table trained elsewhere is), drives
    the same seed's robots to the same summary as the job's own table does."""
    start_worker()
    trained = run(api, TRAIN, FIRST_JOB_S)
    source = api.client.get(f"/jobs/{trained}/qtable").json()
    body = {"states": source["states"], "actions": source["actions"], "values": source["values"]}
    sent = api.client.post("/policies", json=body)
    assert sent.status_code == 201, sent.text
    policy = sent.json()

    from_job = run(api, {**EVALUATE, "policy_from": trained})
    from_policy = run(api, {**EVALUATE, "policy_from": policy["policy_from"]})

    job = api.client.get(f"/jobs/{from_policy}").json()
    assert job["scenario"]["policy_from"] == policy["policy_from"]
    assert summary(api, from_policy) == summary(api, from_job)
    assert summary(api, from_policy) != summary(api, run(api, EVALUATE))
    evaluated = api.client.get(f"/jobs/{from_policy}/qtable").json()
    assert evaluated["values"] == source["values"]  # evaluated greedily, not trained further
