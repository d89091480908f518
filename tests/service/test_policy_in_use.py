"""A delete of a policy that races a submit naming it, through a real server on SQLite and on
PostgreSQL: either the job (or the study) is queued and the delete is refused with 409, or the
policy is deleted and the submit is refused with 422 at ``policy_from``; never both, so that no
queued job is left without its policy."""

from __future__ import annotations

import threading
from typing import Any

import pytest

from nanonav.engine import qlearning
from nanonav.settings import Settings
from tests.conftest import SCRIPTED
from tests.service.test_security import Served, served

ROUNDS = 12
EVALUATE: dict[str, Any] = {"robots": {"count": 2}, "learning": {"episodes": 0, "max_steps": 30}}


def send_policy(api: Served) -> dict[str, Any]:
    states, actions = qlearning.labels("behaviors")
    values = [[float(i + j) for j in range(len(actions))] for i in range(len(states))]
    response = api.client.post(
        "/policies", json={"states": states, "actions": actions, "values": values}, headers=SCRIPTED
    )
    assert response.status_code == 201, response.text
    answer: dict[str, Any] = response.json()
    return answer


def race(api: Served, path: str, body: dict[str, Any], policy_id: int) -> tuple[Any, Any]:
    """The submit's and the delete's answers, both sent at once."""
    start = threading.Barrier(2)
    answers: dict[str, Any] = {}

    def submit() -> None:
        start.wait()
        answers["submit"] = api.client.post(path, json=body, headers=SCRIPTED)

    def delete() -> None:
        start.wait()
        answers["delete"] = api.client.delete(f"/policies/{policy_id}", headers=SCRIPTED)

    threads = [threading.Thread(target=submit), threading.Thread(target=delete)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join(60)
    return answers["submit"], answers["delete"]


@pytest.mark.parametrize("what", ["job", "study"])
def test_a_policy_is_deleted_or_evaluated_never_both(database_url: str, what: str) -> None:
    outcomes = []
    with served(Settings(database_url=database_url)) as api:
        for _ in range(ROUNDS):
            policy = send_policy(api)
            scenario = {**EVALUATE, "policy_from": policy["policy_from"]}
            if what == "job":
                path, body, loc = "/jobs", scenario, ["body", "policy_from"]
            else:
                path, body = "/studies", {"base": scenario, "seeds": [1, 2]}
                loc = ["body", "base", "policy_from"]
            submitted, deleted = race(api, path, body, policy["id"])
            outcomes.append((submitted.status_code, deleted.status_code))
            if submitted.status_code == 202:
                assert deleted.status_code == 409, deleted.text
                assert deleted.json()["type"].endswith("policy-in-use")
                kept = api.client.get(f"/policies/{policy['id']}", headers=SCRIPTED)
                assert kept.status_code == 200
            else:
                assert (submitted.status_code, deleted.status_code) == (422, 204), submitted.text
                [error] = submitted.json()["errors"]
                assert (error["loc"], error["type"]) == (loc, "policy_unusable")
                assert error["detail"] == f"there is no policy {policy['id']}"
        # Every job queued evaluates a policy that is still there.
        jobs = api.client.get("/jobs?limit=100", headers=SCRIPTED).json()["jobs"]
        for job in jobs:
            name = job["scenario"]["policy_from"]
            assert api.client.get(f"/policies/{name.removeprefix('policy-')}").status_code == 200
    assert len(outcomes) == ROUNDS
