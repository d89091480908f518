"""Policies through the API: a table made elsewhere is sent as values or as a greedy table,
refused with a 422 naming its field when it is not one the engine can evaluate, shown, listed,
deleted and scoped to its key; jobs and studies that name it are checked as a job's table is."""

from __future__ import annotations

import json
import threading
from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest
from sqlalchemy import delete

from nanonav.client import Client, PolicyDetail
from nanonav.engine import qlearning
from nanonav.policy import MAX_Q, greedy_table
from nanonav.settings import Settings
from nanonav.store import JobStatus, Outcome
from nanonav.store.models import Policy as PolicyRow
from tests.conftest import SCRIPTED, Api
from tests.service.test_api import assert_problem
from tests.service.test_security import KEY_A, KEY_B, Served, bearer, served
from worker.job import run_job

BEHAVIORS = qlearning.labels("behaviors")
EVALUATE: dict[str, Any] = {"robots": {"count": 2}, "learning": {"episodes": 0, "max_steps": 60}}


def table(shape: tuple[int, ...], seed: int = 0) -> list[Any]:
    """Distinct values, so that every state has one best action."""
    values: list[Any] = np.random.default_rng(seed).normal(size=shape).round(6).tolist()
    return values


def send(api: Api, body: dict[str, Any]) -> dict[str, Any]:
    response = api.client.post("/policies", json=body)
    assert response.status_code == 201, response.text
    answer: dict[str, Any] = response.json()
    assert response.headers["location"] == answer["links"]["self"] == f"/policies/{answer['id']}"
    return answer


def behaviors_policy(api: Api, robots: int | None = None) -> dict[str, Any]:
    states, actions = BEHAVIORS
    shape = (len(states), len(actions)) if robots is None else (robots, len(states), len(actions))
    return send(api, {"states": states, "actions": actions, "values": table(shape)})


def refused(api: Api, body: Any, path: str = "/policies") -> tuple[str, str, str]:
    """The pointer, rule and detail of the one field a 422 names."""
    problem = assert_problem(api.client.post(path, json=body), 422)
    [error] = problem["errors"]
    assert problem["detail"] == f"{error['pointer']}: {error['detail']}"
    return error["pointer"], error["type"], error["detail"]


# ---------------------------------------------------------------- sending a table


def test_a_values_table_is_kept_and_shown_with_its_greedy_table(api: Api) -> None:
    states, actions = BEHAVIORS
    values = table((72, 4), seed=1)
    values[5] = [0.0, 0.0, 0.0, 0.0]
    body = {"name": "from PPO", "states": states, "actions": actions, "values": values}
    sent = send(api, body)
    assert sent["policy_from"] == f"policy-{sent['id']}"
    assert {k: sent[k] for k in ("name", "action_set", "communication", "per_robot")} == {
        "name": "from PPO",
        "action_set": "behaviors",
        "communication": ["none"],
        "per_robot": False,
    }
    assert (sent["state_count"], sent["action_count"], sent["table_count"]) == (72, 4, 1)
    shown = api.client.get(sent["links"]["self"]).json()
    assert {k: shown[k] for k in sent} == sent
    assert (shown["states"], shown["actions"], shown["values"]) == (states, actions, values)
    expected = greedy_table(states, actions, np.array(values), np.zeros((72, 4), dtype=np.int64))
    assert shown["greedy"] == [g.to_dict() for g in expected]
    assert shown["greedy"][0]["action"] == actions[int(np.argmax(values[0]))]
    assert shown["greedy"][5]["action"] == "unvisited"


def test_a_greedy_table_becomes_ones_for_the_chosen_action_and_gives_it_back(
    api: Api, trained: int
) -> None:
    source = api.client.get(f"/jobs/{trained}/qtable").json()
    assert {g["action"] for g in source["greedy"]} > {"unvisited"}
    body = {"states": source["states"], "actions": source["actions"], "greedy": source["greedy"]}
    shown = api.client.get(send(api, body)["links"]["self"]).json()
    assert [g["action"] for g in shown["greedy"]] == [g["action"] for g in source["greedy"]]
    for choice, row in zip(source["greedy"], shown["values"], strict=True):
        expected = [0.0] * 4
        if choice["action"] != "unvisited":
            expected[source["actions"].index(choice["action"])] = 1.0
        assert row == expected
    # a state left out is a row of zeros, as an unvisited one
    few = {**body, "greedy": [{"state": source["states"][3], "action": "explore"}]}
    values = np.array(api.client.get(send(api, few)["links"]["self"]).json()["values"])
    assert values.sum() == 1.0 and values[3, 3] == 1.0


def test_per_robot_tables_and_the_communication_layouts_are_recognised(api: Api) -> None:
    sent = behaviors_policy(api, robots=3)
    assert (sent["table_count"], sent["per_robot"]) == (3, True)
    states, actions = qlearning.labels("steering", "attractant_repellent")
    steering = send(api, {"states": states, "actions": actions, "values": table((128, 5))})
    assert steering["action_set"] == "steering"
    assert steering["communication"] == ["attractant", "attractant_repellent"]
    states, actions = qlearning.labels("directions")
    directions = send(api, {"states": states, "actions": actions, "values": table((54, 26))})
    assert (directions["action_set"], directions["communication"]) == ("directions", ["none"])


# ---------------------------------------------------------------- what is refused


def test_labels_that_are_no_layouts_are_422_naming_the_field_and_what_would_do(api: Api) -> None:
    states, actions = BEHAVIORS
    values = table((72, 4))
    pointer, rule, detail = refused(api, {"states": states, "actions": ["up"], "values": values})
    assert (pointer, rule) == ("#/actions", "policy_layout")
    assert detail.startswith("1 actions that are not those of any action set; the engine's are ")
    assert "'directions': 26 (move(-x,-y,-z), move(-x,-y,0z), move(-x,-y,+z), ..., " in detail
    swapped = [actions[1], actions[0], *actions[2:]]
    pointer, _, detail = refused(api, {"states": states, "actions": swapped, "values": values})
    assert pointer == "#/actions"
    assert detail.startswith("these are the actions of 'behaviors' in another order")
    signal = [*actions, "follow_signal"]
    pointer, _, detail = refused(api, {"states": states, "actions": signal, "values": values})
    assert (pointer, detail) == (
        "#/states",
        "72 states, and the actions are those of 'behaviors' with communication.model "
        "'attractant', 'attractant_repellent' or 'broadcast', whose layouts have 288 "
        "('behaviors' with communication.model 'attractant' or 'attractant_repellent') or 144 "
        "('behaviors' with communication.model 'broadcast')",
    )
    typo = [*states[:7], "conc=low|trend=up", *states[8:]]
    pointer, _, detail = refused(api, {"states": typo, "actions": actions, "values": values})
    assert pointer == "#/states"
    assert detail.startswith("states[7] is 'conc=low|trend=up' where the 72 states of 'behaviors'")
    shuffled = states[::-1]
    assert "in another order" in refused(api, {"states": shuffled, "actions": actions})[2]


def test_values_of_the_wrong_shape_or_kind_are_422_at_values(api: Api) -> None:
    states, actions = BEHAVIORS
    cases = [
        (table((72, 3)), "values[0] is not a row of 4 values, one per action"),
        (
            table((71, 4)),
            "values has 71 rows where 'behaviors' with communication.model 'none' has 72 states",
        ),
        ([table((72, 4)), table((70, 4))], "values[1] has 70 rows where"),
        (
            [[1, "x"]],
            "values must be a table of numbers, states x actions, or robots x states x "
            "actions: at values[0][1], input should be a valid number",
        ),
        ([[[0.0]]] * 1001, "at values, list should have at most 1000 items"),
        ([[[0.0], [True]]], "at values[0][1][0], input should be a valid number"),
        ([], "list should have at least 1 item"),
    ]
    for values, detail in cases:
        body = {"states": states, "actions": actions, "values": values}
        pointer, rule, found = refused(api, body)
        assert pointer == "#/values" and rule in {"policy_table", "table"}
        assert detail in found, found


def test_a_value_that_is_not_finite_is_422_naming_where(api: Api) -> None:
    states, actions = BEHAVIORS
    values = table((72, 4))
    values[9][2] = float("nan")
    body = {"states": states, "actions": actions, "values": values}
    content = json.dumps(body)  # NaN is not JSON, but Python writes and reads it
    response = api.client.post(
        "/policies", content=content, headers={"content-type": "application/json"}
    )
    problem = assert_problem(response, 422)
    assert problem["errors"][0]["pointer"] == "#/values"
    assert problem["errors"][0]["detail"] == (
        "values[9][2] is nan: every value must be a finite number"
    )


def test_a_value_beyond_the_bound_is_422_and_a_table_a_job_learned_is_taken_back(
    api: Api, trained: int
) -> None:
    states, actions = BEHAVIORS
    for huge in (1.7e308, -1.0000001e30):
        values = np.asarray(table((2, 72, 4)))
        values[1, 4, 3] = huge
        body = {"states": states, "actions": actions, "values": values.tolist()}
        assert refused(api, body) == (
            "#/values",
            "policy_table",
            f"values[1][4][3] is {huge:g}: every value must be within +-1e+30, beyond what any "
            "job learns",
        )
    values[1, 4, 3] = -MAX_Q
    assert send(api, {**body, "values": values.tolist()})["table_count"] == 2
    learned = api.client.get(f"/jobs/{trained}/qtable").json()
    assert np.abs(learned["values"]).max() > 0
    sent = send(api, {k: learned[k] for k in ("states", "actions", "values")})
    assert api.client.get(sent["links"]["self"]).json()["values"] == learned["values"]


def test_greedy_choices_that_do_not_fit_are_422_at_their_own_item(api: Api) -> None:
    states, actions = BEHAVIORS
    base = {"states": states, "actions": actions}
    choices = [{"state": s, "action": "explore", "visits": 3} for s in states[:4]]
    unknown = [*choices[:3], {"state": "conc=none", "action": "explore"}]
    pointer, rule, detail = refused(api, {**base, "greedy": unknown})
    assert (pointer, rule) == ("#/greedy/3/state", "policy_table")
    assert detail.startswith("'conc=none' is not a state of 'behaviors' with communication")
    twice = [*choices[:3], choices[1]]
    assert refused(api, {**base, "greedy": twice})[::2] == (
        "#/greedy/3/state",
        f"{states[1]!r} is given twice: at greedy/1 too",
    )
    wrong = [*choices[:2], {"state": states[2], "action": "jump"}]
    assert refused(api, {**base, "greedy": wrong})[::2] == (
        "#/greedy/2/action",
        "'jump' is neither an action of 'behaviors' with communication.model 'none' "
        "(follow_gradient, approach_cell, avoid_obstacle, explore) nor 'unvisited'",
    )
    missing = assert_problem(api.client.post("/policies", json={**base, "greedy": [{}]}), 422)
    assert {e["pointer"] for e in missing["errors"]} == {"#/greedy/0/state", "#/greedy/0/action"}


def test_exactly_one_table_is_sent_and_nothing_else(api: Api) -> None:
    states, actions = BEHAVIORS
    base = {"states": states, "actions": actions}
    for body, given in (
        (base, "neither"),
        ({**base, "values": table((72, 4)), "greedy": []}, "both"),
    ):
        problem = assert_problem(api.client.post("/policies", json=body), 422)
        assert [(e["pointer"], e["type"]) for e in problem["errors"]] == [
            ("#/values", "policy_table"),
            ("#/greedy", "policy_table"),
        ]
        assert problem["detail"] == f"give exactly one of values and greedy, not {given}"
    extra = {**base, "greedy": [], "visits": [[0]]}
    assert refused(api, extra)[:2] == ("#/visits", "extra_forbidden")
    assert api.client.get("/policies").json()["policies"] == []


def test_a_body_over_the_size_limit_is_413(api: Api) -> None:
    states, actions = BEHAVIORS
    body = {"states": states, "actions": actions, "values": table((100, 72, 4))}
    assert_problem(api.client.post("/policies", json=body), 413)


# ---------------------------------------------------------------- reading and deleting


def test_policies_are_listed_newest_first_a_page_at_a_time_and_deleted(api: Api) -> None:
    ids = [behaviors_policy(api)["id"] for _ in range(3)]
    first = api.client.get("/policies", params={"limit": 2}).json()
    assert [p["id"] for p in first["policies"]] == [ids[2], ids[1]]
    assert "values" not in first["policies"][0]
    rest = api.client.get(first["next"]).json()
    assert [p["id"] for p in rest["policies"]] == [ids[0]] and rest["next"] is None
    assert api.client.get(f"/policies/policy-{ids[1]}").json()["id"] == ids[1]
    assert_problem(api.client.get(f"/policies/0{ids[1]}"), 404)
    assert assert_problem(api.client.get("/policies/two"), 422)["errors"][0]["loc"] == [
        "path",
        "policy_id",
    ]
    assert api.client.delete(f"/policies/{ids[1]}").status_code == 204
    for method in ("GET", "DELETE"):
        gone = assert_problem(api.client.request(method, f"/policies/{ids[1]}"), 404)
        assert gone["type"].endswith("policy-not-found")
        assert gone["detail"] == f"there is no policy {ids[1]}"
    listed = api.client.get("/policies").json()["policies"]
    assert [p["id"] for p in listed] == [ids[2], ids[0]]


def test_the_client_sends_lists_reads_and_deletes_policies(api: Api) -> None:
    states, actions = BEHAVIORS
    values = np.asarray(table((2, 72, 4)))
    with Client(api.url) as client:
        sent = client.send_policy(states, actions, values=values, name="two robots")
        assert (sent.policy_from, sent.table_count, sent.per_robot) == (
            f"policy-{sent.id}",
            2,
            True,
        )
        detail = client.policy(sent.id)
        assert isinstance(detail, PolicyDetail) and detail.per_robot and detail.memory is None
        assert np.array_equal(np.asarray(detail.values), values)
        assert detail.states == list(states) and detail.actions == list(actions)
        greedy = client.send_policy(
            states, actions, greedy=[{"state": states[0], "action": "explore"}]
        )
        assert [p.id for p in client.policies()] == [greedy.id, sent.id]
        client.delete_policy(sent.id)
        assert [p.id for p in client.policies()] == [greedy.id]


# ---------------------------------------------------------------- jobs and studies naming one


def test_a_job_evaluates_a_fitting_policy_and_is_refused_one_that_does_not_fit(
    api: Api,
) -> None:
    shared = behaviors_policy(api)["policy_from"]
    per_robot = behaviors_policy(api, robots=2)["policy_from"]
    accepted = api.client.post("/jobs", json={**EVALUATE, "policy_from": shared})
    assert accepted.status_code == 202, accepted.text
    assert accepted.json()["scenario"]["policy_from"] == shared
    own = {"robots": {"count": 2}, "learning": {"episodes": 0, "shared_table": False}}
    assert api.client.post("/jobs", json={**own, "policy_from": per_robot}).status_code == 202
    assert api.client.post("/jobs", json={**own, "policy_from": shared}).status_code == 202
    n, m = shared.removeprefix("policy-"), per_robot.removeprefix("policy-")
    directions = {**EVALUATE, "learning": {"episodes": 0, "actions": "directions"}}
    cases = [
        ({**directions, "policy_from": shared}, f"policy {n} has the 'behaviors' actions and "
         "this scenario uses 'directions': learning.actions must be the same"),
        ({**EVALUATE, "policy_from": per_robot}, f"policy {m} has a table per robot and this "
         "scenario's robots share one: learning.shared_table must be false"),
        ({**own, "robots": {"count": 3}, "policy_from": per_robot}, f"policy {m} has a table "
         "for each of its 2 robots and this scenario has 3: robots.count must be the same"),
        ({**EVALUATE, "communication": {"model": "broadcast"}, "policy_from": shared},
         f"policy {n}'s table is laid out for communication.model 'none' and this scenario's "
         "is 'broadcast': communication.model must be the same"),
        ({**EVALUATE, "policy_from": "policy-999"}, "there is no policy 999"),
    ]  # fmt: skip
    for scenario, detail in cases:
        assert refused(api, scenario, "/jobs") == ("#/policy_from", "policy_unusable", detail)
    assert len(api.client.get("/jobs").json()["jobs"]) == 3


def test_a_policy_from_that_names_neither_a_job_nor_a_policy_is_422(api: Api) -> None:
    for value in ("policy-0", "policy-x", "policy-", "7", "Policy-3", 2.5, 0, True):
        pointer, rule, detail = refused(api, {**EVALUATE, "policy_from": value}, "/jobs")
        assert (pointer, rule) == ("#/policy_from", "policy_from")
        assert detail == (
            "must be a job's id (an integer from 1) or a policy's name as POST /policies "
            f"answers it, 'policy-<id>'; not {value!r}"
        )
    assert api.client.get("/jobs").json()["jobs"] == []


def test_a_study_checks_every_policy_its_grid_points_name(api: Api, trained: int) -> None:
    policy = behaviors_policy(api)["policy_from"]
    grid = {"base": EVALUATE, "grid": {"policy_from": [trained, policy]}, "seeds": [1]}
    response = api.client.post("/studies", json=grid)
    assert response.status_code == 202, response.text
    assert response.json()["jobs"]["total"] == 2
    missing = {**grid, "grid": {"policy_from": [policy, "policy-999"]}}
    assert refused(api, missing, "/studies") == (
        "#/grid/policy_from/1",
        "policy_unusable",
        "there is no policy 999",
    )
    actions = {
        "base": {**EVALUATE, "policy_from": policy},
        "grid": {"learning.actions": ["behaviors", "directions"]},
        "seeds": [1],
    }
    pointer, rule, detail = refused(api, actions, "/studies")
    assert (pointer, rule) == ("#/base/policy_from", "policy_unusable")
    assert detail.startswith("at the grid point {'learning.actions': 'directions'}: policy ")


def test_a_jobs_table_learned_with_a_communication_model_fits_that_models_layout(
    api: Api,
) -> None:
    """A job's table has the layout of its communication model: it fits a scenario that senses
    the same states, and is refused, saying why, by one that does not."""
    states, actions = qlearning.labels("behaviors", "attractant")
    job = api.store.enqueue({}, robot_steps=1, episodes=1)
    claim = api.store.claim("test", lease_s=30)
    assert claim is not None and claim.job.id == job.id
    qtable = {
        "states": np.array(states, dtype=np.str_),
        "actions": np.array(actions, dtype=np.str_),
        "values": np.ones((len(states), len(actions))),
        "visits": np.ones((len(states), len(actions)), dtype=np.int64),
    }
    api.store.finish(claim, Outcome(completed=True, metrics={}, trajectory=None, qtable=qtable))
    assert api.store.get(job.id).status is JobStatus.SUCCEEDED
    for model in ("attractant", "attractant_repellent"):
        scenario = {**EVALUATE, "communication": {"model": model}, "policy_from": job.id}
        assert api.client.post("/jobs", json=scenario).status_code == 202
    broadcast = {**EVALUATE, "communication": {"model": "broadcast"}, "policy_from": job.id}
    assert refused(api, broadcast, "/jobs")[2] == (
        f"job {job.id}'s table is laid out for communication.model 'attractant' or "
        "'attractant_repellent' and this scenario's is 'broadcast': communication.model must "
        "be one of them"
    )


def test_a_steering_policy_drives_active_brownian_robots(api: Api) -> None:
    states, actions = qlearning.labels("steering", "broadcast")
    policy = send(api, {"states": states, "actions": actions, "values": table((64, 5))})
    brownian = {
        "physics": {"model": "active_brownian"},
        "robots": {"count": 2},
        "learning": {"episodes": 0},
        "policy_from": policy["policy_from"],
    }
    fits = {**brownian, "communication": {"model": "broadcast"}}
    assert api.client.post("/jobs", json=fits).status_code == 202
    assert "laid out for communication.model 'broadcast'" in refused(api, brownian, "/jobs")[2]


# ---------------------------------------------------------------- owners


@pytest.fixture
def keyed(sqlite_url: str) -> Iterator[Served]:
    with served(Settings(database_url=sqlite_url, api_keys=f"{KEY_A},{KEY_B}")) as api:
        yield api


def test_another_keys_policy_is_not_there_for_reading_deleting_or_naming(keyed: Served) -> None:
    states, actions = BEHAVIORS
    body = {"states": states, "actions": actions, "values": table((72, 4))}
    response = keyed.client.post("/policies", json=body, headers=bearer(KEY_A))
    assert response.status_code == 201, response.text
    policy_id, name = response.json()["id"], response.json()["policy_from"]
    for method in ("GET", "DELETE"):
        theirs = keyed.client.request(method, f"/policies/{policy_id}", headers=bearer(KEY_B))
        absent = keyed.client.request(method, "/policies/999", headers=bearer(KEY_B))
        assert assert_problem(theirs, 404)["type"] == assert_problem(absent, 404)["type"]
    assert keyed.client.get("/policies", headers=bearer(KEY_B)).json()["policies"] == []
    listed = keyed.client.get("/policies", headers=bearer(KEY_A)).json()["policies"]
    assert [p["id"] for p in listed] == [policy_id]
    scenario = {**EVALUATE, "policy_from": name}
    refusal = assert_problem(keyed.client.post("/jobs", json=scenario, headers=bearer(KEY_B)), 422)
    assert refusal["errors"][0]["detail"] == f"there is no policy {policy_id}"
    study = {"base": scenario, "seeds": [1]}
    assert_problem(keyed.client.post("/studies", json=study, headers=bearer(KEY_B)), 422)
    mine = keyed.client.post("/jobs", json=scenario, headers=bearer(KEY_A))
    assert mine.status_code == 202, mine.text
    claim = keyed.store.claim("test", lease_s=30)
    assert claim is not None
    record = run_job(keyed.store, claim, keyed.settings, threading.Event())
    assert record is not None and record.status is JobStatus.SUCCEEDED


def test_a_policy_is_not_deleted_under_the_jobs_that_evaluate_it(
    api: Api, api_settings: Settings
) -> None:
    policy = behaviors_policy(api)
    jobs = [
        api.client.post("/jobs", json={**EVALUATE, "policy_from": policy["policy_from"]}).json()
        for _ in range(2)
    ]
    other = behaviors_policy(api)
    api.client.post("/jobs", json={**EVALUATE, "policy_from": other["policy_from"]})
    in_use = assert_problem(api.client.delete(policy["links"]["self"]), 409)
    assert in_use["type"].endswith("policy-in-use")
    assert in_use["detail"] == (
        f"policy {policy['id']} is evaluated by 2 queued or running job(s) "
        f"({jobs[0]['id']}, {jobs[1]['id']}): cancel them, or wait for them to finish, then "
        "delete it"
    )
    assert api.client.post(f"/jobs/{jobs[0]['id']}/cancel").status_code == 200
    claim = api.store.claim("test", lease_s=30)
    assert claim is not None and claim.job.id == jobs[1]["id"]
    running = assert_problem(api.client.delete(policy["links"]["self"]), 409)
    assert f"by 1 queued or running job(s) ({jobs[1]['id']})" in running["detail"]
    record = run_job(api.store, claim, api_settings, threading.Event())
    assert record is not None and record.status is JobStatus.SUCCEEDED
    assert api.client.delete(policy["links"]["self"]).status_code == 204
    assert api.client.get(f"/jobs/{jobs[1]['id']}/metrics").status_code == 200


def test_a_job_whose_policy_is_gone_when_it_runs_fails_saying_so(
    api: Api, api_settings: Settings
) -> None:
    """A job that a worker claims after its policy's row went some other way than through a
    refused delete (a database restored from an older backup, say) fails with the reason; a
    delete itself never leaves such a job (tests/store/test_policy_in_use.py)."""
    policy = behaviors_policy(api)
    job = api.store.enqueue(
        {**EVALUATE, "policy_from": policy["policy_from"]}, robot_steps=1, episodes=0
    )
    with api.store.engine.begin() as connection:
        connection.execute(delete(PolicyRow).where(PolicyRow.id == policy["id"]))
    claim = api.store.claim("test", lease_s=30)
    assert claim is not None and claim.job.id == job.id
    record = run_job(api.store, claim, api_settings, threading.Event())
    assert record is not None and record.status is JobStatus.FAILED
    assert record.error == f"policy_from: there is no policy {policy['id']}"


def test_the_same_idempotency_key_gives_the_same_policy_and_another_body_is_422(
    api: Api,
) -> None:
    states, actions = BEHAVIORS
    body = {"states": states, "actions": actions, "values": table((72, 4))}
    key = {"Idempotency-Key": "trained-on-seed-7"}
    first = api.client.post("/policies", json=body, headers=key)
    again = api.client.post("/policies", content=json.dumps(body, indent=1), headers={
        **key, "Content-Type": "application/json"})  # fmt: skip
    assert first.status_code == again.status_code == 201, again.text
    assert first.json() == again.json()
    assert len(api.client.get("/policies").json()["policies"]) == 1
    changed = {**body, "name": "another"}
    problem = assert_problem(api.client.post("/policies", json=changed, headers=key), 422)
    assert problem["errors"][0]["type"] == "idempotency_key_reused"
    assert f"(it made policy {first.json()['id']})" in problem["detail"]
    blank = assert_problem(
        api.client.post("/policies", json=body, headers={"Idempotency-Key": ""}), 422
    )
    assert blank["errors"][0]["loc"] == ["header", "idempotency-key"]
    with Client(api.url) as client:
        sent = client.send_policy(states, actions, values=body["values"], idempotency_key="k2")
        assert (
            client.send_policy(states, actions, values=body["values"], idempotency_key="k2") == sent
        )


@pytest.mark.parametrize("keys", [False, True], ids=["no keys", "per key"])
def test_a_key_keeps_at_most_quota_policies_and_may_send_again_after_a_delete(
    sqlite_url: str, keys: bool
) -> None:
    settings = Settings(
        database_url=sqlite_url, quota_policies=2, api_keys=f"{KEY_A},{KEY_B}" if keys else ""
    )
    states, actions = BEHAVIORS
    body = {"states": states, "actions": actions, "values": table((72, 4))}
    with served(settings) as api:
        a = bearer(KEY_A) if keys else SCRIPTED
        sent = [api.client.post("/policies", json=body, headers=a) for _ in range(2)]
        assert [r.status_code for r in sent] == [201, 201]
        full = assert_problem(api.client.post("/policies", json=body, headers=a), 409)
        assert full["type"].endswith("policy-limit")
        assert full["detail"].startswith("this key already keeps 2 policies")
        if keys:
            theirs = api.client.post("/policies", json=body, headers=bearer(KEY_B))
            assert theirs.status_code == 201, "another key's policies are its own"
        gone = api.client.delete(f"/policies/{sent[0].json()['id']}", headers=a)
        assert gone.status_code == 204
        assert api.client.post("/policies", json=body, headers=a).status_code == 201
