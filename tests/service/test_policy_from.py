"""A policy_from that names no usable table is refused at submit, for a job (``#/policy_from``)
and for every grid point of a study (the base's field or the grid value), saying why."""

from __future__ import annotations

from typing import Any

from nanonav.settings import Settings
from tests.conftest import Api
from tests.service.conftest import TINY, ran
from tests.service.test_api import assert_problem

EVALUATE: dict[str, Any] = {"robots": {"count": 2}, "learning": {"episodes": 0, "max_steps": 60}}


def refused(api: Api, path: str, body: dict[str, Any]) -> tuple[str, str]:
    """The pointer and detail of the one field a 422 names."""
    problem = assert_problem(api.client.post(path, json=body), 422)
    [error] = problem["errors"]
    assert problem["detail"] == f"{error['pointer']}: {error['detail']}"
    return error["pointer"], error["detail"]


def test_a_job_may_evaluate_a_succeeded_jobs_fitting_table(api: Api, trained: int) -> None:
    response = api.client.post("/jobs", json={**EVALUATE, "policy_from": trained})
    assert response.status_code == 202, response.text
    assert response.json()["scenario"]["policy_from"] == trained
    per_robot = {"robots": {"count": 3}, "learning": {"episodes": 0, "shared_table": False}}
    assert api.client.post("/jobs", json={**per_robot, "policy_from": trained}).status_code == 202


def test_a_policy_from_naming_no_usable_table_is_422_saying_why(
    api: Api, api_settings: Settings, trained: int
) -> None:
    assert refused(api, "/jobs", {**EVALUATE, "policy_from": 999}) == (
        "#/policy_from",
        "there is no job 999",
    )
    failed = ran(api.store, api_settings, {"robots": {"count": -1}})
    assert refused(api, "/jobs", {**EVALUATE, "policy_from": failed})[1].startswith(
        f"job {failed} is failed"
    )
    baseline = ran(api.store, api_settings, {**TINY, "robots": {"count": 1, "policy": "gradient"}})
    assert refused(api, "/jobs", {**EVALUATE, "policy_from": baseline})[1] == (
        f"job {baseline} learned no Q-table: only q_learning jobs do"
    )
    directions = {**EVALUATE, "learning": {"episodes": 0, "actions": "directions"}}
    assert refused(api, "/jobs", {**directions, "policy_from": trained})[1] == (
        f"job {trained} learned the 'behaviors' actions and this scenario uses 'directions': "
        "learning.actions must be the same"
    )
    queued = api.store.enqueue(TINY, robot_steps=1, episodes=3).id
    assert refused(api, "/jobs", {**EVALUATE, "policy_from": queued}) == (
        "#/policy_from",
        f"job {queued} is queued: only a succeeded job's table can be evaluated",
    )
    stored = api.client.get("/jobs", params={"limit": 100}).json()["jobs"]
    assert [j["scenario"].get("policy_from") for j in stored] == [None] * 4


def test_a_per_robot_table_needs_as_many_robots_learning_their_own(
    api: Api, api_settings: Settings
) -> None:
    own = {**TINY, "learning": {**TINY["learning"], "shared_table": False}}
    source = ran(api.store, api_settings, own)
    pointer, detail = refused(api, "/jobs", {**EVALUATE, "policy_from": source})
    assert pointer == "#/policy_from" and "learning.shared_table must be false" in detail
    three = {"robots": {"count": 3}, "learning": {"episodes": 0, "shared_table": False}}
    pointer, detail = refused(api, "/jobs", {**three, "policy_from": source})
    assert "each of its 2 robots and this scenario has 3" in detail
    two = {"robots": {"count": 2}, "learning": {"episodes": 0, "shared_table": False}}
    assert api.client.post("/jobs", json={**two, "policy_from": source}).status_code == 202


def test_a_study_names_where_its_unusable_policy_from_comes_from(
    api: Api, api_settings: Settings, trained: int
) -> None:
    study = {"base": {**EVALUATE, "policy_from": 999}, "seeds": [1]}
    assert refused(api, "/studies", study) == ("#/base/policy_from", "there is no job 999")
    grid = {"base": EVALUATE, "grid": {"policy_from": [trained, 999]}, "seeds": [1]}
    assert refused(api, "/studies", grid) == ("#/grid/policy_from/1", "there is no job 999")
    actions = {
        "base": {**EVALUATE, "policy_from": trained},
        "grid": {"learning.actions": ["behaviors", "directions"]},
        "seeds": [1],
    }
    pointer, detail = refused(api, "/studies", actions)
    assert pointer == "#/base/policy_from"
    assert detail.startswith("at the grid point {'learning.actions': 'directions'}: job ")
    assert api.client.get("/studies").json()["studies"] == []
    fits = {"base": EVALUATE, "grid": {"policy_from": [trained]}, "seeds": [1, 2]}
    response = api.client.post("/studies", json=fits)
    assert response.status_code == 202, response.text
    assert response.json()["jobs"]["total"] == 2
