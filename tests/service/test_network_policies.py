"""Networks (ONNX models) through the API: sent in base64, checked before they are kept (a 422
naming the field and saying what is wrong, never a 500), shown and listed as networks, named by
jobs whose robots observe and act as the network was trained to, and evaluated by a worker,
which fails a job whose network answers nonsense with the reason."""

from __future__ import annotations

import base64
import re
import threading
from typing import Any

import numpy as np

from nanonav.client import Client
from nanonav.engine.observations import action_labels, observation_of
from nanonav.rl.graph import METADATA_ACTIONS, METADATA_OBSERVATION
from nanonav.scenario import Scenario
from nanonav.settings import Settings
from nanonav.store import JobStatus
from tests.conftest import Api
from tests.rl import models
from tests.service.test_api import assert_problem
from tests.service.test_policies import BEHAVIORS, refused, send
from worker.job import run_job

LATTICE = Scenario()
OBSERVATION = list(observation_of(LATTICE).labels)
ACTIONS = action_labels(LATTICE)
EVALUATE: dict[str, Any] = {
    "robots": {"count": 3, "schedule": "simultaneous"},
    "learning": {"episodes": 0, "max_steps": 80},
    "evaluation": {"worlds": 3},
}


def encoded(model: bytes) -> str:
    return base64.b64encode(model).decode("ascii")


def network(api: Api, model: bytes | None = None, **body: Any) -> dict[str, Any]:
    data = model or models.mlp(len(OBSERVATION), len(ACTIONS))
    return send(
        api, {"onnx": encoded(data), "observation": OBSERVATION, "actions": ACTIONS, **body}
    )


def succeeds(api: Api, settings: Settings, job: int) -> None:
    """The worker runs the next job, ``job``, to success."""
    claim = api.store.claim("test", lease_s=30)
    assert claim is not None and claim.job.id == job
    record = run_job(api.store, claim, settings, threading.Event())
    assert record is not None and record.status is JobStatus.SUCCEEDED, record


def test_a_network_is_kept_shown_and_listed_as_a_network(api: Api) -> None:
    model = models.mlp(len(OBSERVATION), len(ACTIONS))
    sent = network(api, model, name="mlp")
    assert sent["kind"] == "network" and sent["name"] == "mlp"
    assert (sent["state_count"], sent["action_count"]) == (len(OBSERVATION), len(ACTIONS))
    assert sent["action_set"] == "behaviors" and sent["communication"] == ["none"]
    shown = api.client.get(sent["links"]["self"]).json()
    assert shown["observation"] == OBSERVATION and shown["actions"] == ACTIONS
    assert shown["model_bytes"] == len(model)
    assert shown["values"] is None and shown["greedy"] is None
    with Client(api.url) as client:
        assert client.network_model(sent["id"]) == model
    table = send(api, {"states": BEHAVIORS[0], "actions": BEHAVIORS[1], "greedy": []})
    no_model = assert_problem(api.client.get(f"/policies/{table['id']}/model"), 404)
    assert no_model["type"].endswith("no-model")
    listed = api.client.get("/policies").json()["policies"]
    assert [p["kind"] for p in listed] == ["table", "network"] and listed[1]["id"] == sent["id"]
    page = api.client.get("/ui/policies")
    assert page.status_code == 200 and "network: 7 observation columns" in page.text


def test_the_labels_may_come_from_the_models_metadata(api: Api) -> None:
    import json

    named = {METADATA_OBSERVATION: json.dumps(OBSERVATION), METADATA_ACTIONS: json.dumps(ACTIONS)}
    model = models.mlp(len(OBSERVATION), len(ACTIONS), metadata=named)
    sent = send(api, {"onnx": encoded(model)})
    assert sent["kind"] == "network" and sent["state_count"] == len(OBSERVATION)
    assert refused(api, {"onnx": encoded(models.mlp(7, 4))}) == (
        "#/observation", "policy_layout",
        "a network needs observation: the model's metadata names none",
    )  # fmt: skip


def test_a_network_that_cannot_decide_is_422_at_the_field_at_fault(api: Api) -> None:
    good = {"observation": OBSERVATION, "actions": ACTIONS}
    width, count = len(OBSERVATION), len(ACTIONS)
    cases: list[tuple[dict[str, Any], str, str, str]] = [
        ({"onnx": encoded(b"not onnx at all"), **good}, "#/onnx", "policy_model",
         "this is not an ONNX model"),
        ({"onnx": encoded(models.mlp(width, 6)), **good}, "#/onnx", "policy_model",
         "logits must be (batch, 4), one per action"),
        ({"onnx": encoded(models.custom_operator(width, count)), **good}, "#/onnx",
         "policy_model", "imports the operator set 'com.example'"),
        ({"onnx": encoded(models.external_weights(width, count)), **good}, "#/onnx",
         "policy_model", "keeps its data outside the model"),
        ({"onnx": encoded(models.concatenated(width, count)), **good}, "#/onnx",
         "policy_model", "node 'join' (Concat): the model holds 280,400, over the cap of "
         "262,144, bytes an observation at once here"),
        ({"onnx": encoded(models.dense_stack(width, count, units=1100, layers=4)), **good},
         "#/onnx", "policy_model", "node 'layer3' (MatMul): the model takes 4,874,100, over "
         "the cap of 4,000,000, multiply-adds an observation"),
        ({"onnx": encoded(models.integer_division(width)), **good}, "#/onnx", "policy_model",
         "(Mod): Mod is not an operator a policy needs"),
        ({"onnx": encoded(models.convolutions(width, count)), **good}, "#/onnx",
         "policy_model", "(Expand): Expand is not an operator a policy needs"),
        ({"onnx": encoded(models.far_actions(width)), **good}, "#/onnx", "policy_model",
         "the model answers an action outside 0..3 for a zero observation"),
        ({"onnx": encoded(models.mlp(3, count)), "observation": ["reading", "reading_change",
          "gradient_x"], "actions": ACTIONS}, "#/observation", "policy_layout",
         "no scenario's robots observe (reading, reading_change, gradient_x)"),
        ({"onnx": encoded(models.mlp(width, count)), "observation": ["cell", "reading"],
          "actions": ACTIONS}, "#/observation", "policy_layout", "is no robot's observation"),
        ({"onnx": encoded(models.mlp(width, count)), "observation": OBSERVATION,
          "actions": ["a", "b"]}, "#/actions", "policy_layout", "2 actions that are not"),
        ({"onnx": encoded(models.mlp(width, count)), **good, "states": ["x"]}, "#/states",
         "policy_kind", "a network is sent as onnx, observation and actions"),
    ]  # fmt: skip
    for body, pointer, rule, detail in cases:
        found = refused(api, body)
        assert found[:2] == (pointer, rule) and detail in found[2], found
    not_base64 = assert_problem(
        api.client.post("/policies", json={"onnx": "%%% not base64", **good}), 422
    )
    assert not_base64["errors"][0]["pointer"] == "#/onnx"
    table_without_states = refused(api, {"actions": ACTIONS, "values": [[0.0] * count]})
    assert table_without_states[:2] == ("#/states", "policy_kind")
    assert api.client.get("/policies").json()["policies"] == []


def test_a_job_names_a_network_whose_robots_observe_and_act_as_it_was_trained(
    api: Api,
) -> None:
    policy = network(api)["policy_from"]
    accepted = api.client.post("/jobs", json={**EVALUATE, "policy_from": policy})
    assert accepted.status_code == 202, accepted.text
    n = policy.removeprefix("policy-")
    directions = {**EVALUATE, "learning": {"episodes": 0, "actions": "directions"}}
    broadcast = {**EVALUATE, "communication": {"model": "broadcast"}}
    heard = Scenario.model_validate(broadcast)
    listens = list(observation_of(heard).labels)
    spoken = action_labels(heard)
    other = network(api, models.mlp(len(listens), len(spoken)), observation=listens,
                    actions=spoken)  # fmt: skip
    m = other["id"]
    assert other["communication"] == ["broadcast"]
    sent = api.client.post("/jobs", json={**broadcast, "policy_from": f"policy-{m}"})
    assert sent.status_code == 202, sent.text
    chemical = {**EVALUATE, "communication": {"model": "attractant"}}
    cases = [
        ({**EVALUATE, "physics": {"model": "active_brownian"}}, policy,
         f"policy {n} chooses among the 'behaviors' actions and this scenario uses 'steering': "
         "learning.actions must be the same"),
        (directions, policy,
         f"policy {n} chooses among the 'behaviors' actions and this scenario uses "
         "'directions': learning.actions must be the same"),
        (chemical, f"policy-{m}",
         f"policy {m} reads ({', '.join(listens)}) and this scenario's robots observe "
         f"({', '.join(listens)}, signal_change): physics.model and communication.model must "
         "be those it was trained in"),
    ]  # fmt: skip
    for scenario, source, detail in cases:
        pointer, rule, found = refused(api, {**scenario, "policy_from": source}, "/jobs")
        assert (pointer, rule, found) == ("#/policy_from", "policy_unusable", detail)


def test_a_worker_evaluates_a_network_and_fails_one_that_answers_nonsense(
    api: Api, api_settings: Settings
) -> None:
    """The nonsense comes after the trial run: a recurrent model whose action counts its
    decisions answers one past the last action at the fourth."""
    good = network(api)["policy_from"]
    bad = network(api, models.counting_past(len(OBSERVATION)))
    jobs = [
        api.client.post("/jobs", json={**EVALUATE, "policy_from": source}).json()["id"]
        for source in (good, bad["policy_from"])
    ]
    records = []
    for _ in jobs:
        claim = api.store.claim("test", lease_s=30)
        assert claim is not None
        records.append(run_job(api.store, claim, api_settings, threading.Event()))
    done, failed = records
    assert done is not None and done.status is JobStatus.SUCCEEDED, done
    metrics = api.client.get(f"/jobs/{jobs[0]}/metrics").json()
    assert len(metrics["worlds"]) == 3 and 0.0 <= metrics["summary"]["success_rate"] <= 1.0
    trajectory = api.client.get(f"/jobs/{jobs[0]}/trajectory").json()
    assert np.asarray(trajectory["robots"]).shape[1:] == (3, 3)
    assert api.client.get(f"/jobs/{jobs[0]}/plots/trajectory.png").status_code == 200
    assert api.client.get(f"/jobs/{jobs[0]}/plots/learning.png").status_code == 200
    assert metrics["work"]["decide_calls"] > 0  # the network decided, not an engine's table
    no_table = assert_problem(api.client.get(f"/jobs/{jobs[0]}/plots/qtable.png"), 404)
    assert no_table["detail"] == (
        f"job {jobs[0]} learned no Q-table: it evaluated {good}, a network, which has none"
    )
    page = api.client.get(f"/ui/jobs/{jobs[0]}").text
    assert "Decided by the network" in page and "plots/qtable.png" not in page
    assert failed is not None and failed.status is JobStatus.FAILED
    assert re.fullmatch(
        r"policy_from: the policy raised ValueError: the model answers an action outside "
        r"0\.\.3 for (a zero observation|the observation \([-\d., e+]+\))",
        failed.error or "",
    ), failed.error


def test_a_recurrent_network_is_kept_with_its_memory_and_evaluated_at_once(
    api: Api, api_settings: Settings
) -> None:
    sent = network(api, models.counter(len(OBSERVATION), len(ACTIONS)))
    assert api.client.get(sent["links"]["self"]).json()["memory"] == 1
    source, n = sent["policy_from"], sent["id"]
    in_turns = {**EVALUATE, "robots": {"count": 3, "schedule": "sequential"}}
    pointer, rule, detail = refused(api, {**in_turns, "policy_from": source}, "/jobs")
    assert (pointer, rule) == ("#/policy_from", "policy_unusable")
    assert detail == (
        f"policy {n} has a memory: a network with a memory decides for every robot at once, "
        "each row one robot: robots.schedule must be 'simultaneous'"
    )
    job = api.client.post("/jobs", json={**EVALUATE, "policy_from": source}).json()["id"]
    succeeds(api, api_settings, job)


def test_a_network_that_turns_steers_active_brownian_robots(
    api: Api, api_settings: Settings
) -> None:
    """A network whose actions are a continuous turn (``turn_side``, ``turn_up``) reads the
    gradient in the body frame, is refused where robots cannot turn, and is evaluated by a
    worker where they can."""
    swimmers = {**EVALUATE, "physics": {"model": "active_brownian"}}
    reads = list(observation_of(Scenario.model_validate(swimmers), "continuous").labels)
    assert "gradient_side" in reads
    turns = ["turn_side", "turn_up"]
    sent = network(api, models.mlp(len(reads), 2), observation=reads, actions=turns)
    assert sent["kind"] == "network" and sent["action_set"] == "steering"
    assert api.client.get(sent["links"]["self"]).json()["actions"] == turns
    source, n = sent["policy_from"], sent["id"]
    cases = [
        ({"onnx": encoded(models.mlp(len(reads), 3)), "observation": reads, "actions": turns},
         "#/onnx", "policy_model", "a turn must be floats (batch, 2)"),
        ({"onnx": encoded(models.mlp(len(OBSERVATION), 2)), "observation": OBSERVATION,
          "actions": turns}, "#/observation", "policy_layout", "gradient_forward"),
    ]  # fmt: skip
    for body, pointer, rule, detail in cases:
        found = refused(api, body)
        assert found[:2] == (pointer, rule) and detail in found[2], found
    pointer, rule, detail = refused(api, {**EVALUATE, "policy_from": source}, "/jobs")
    assert (pointer, rule) == ("#/policy_from", "policy_unusable")
    assert detail == (
        f"policy {n} steers by a continuous turn (turn_side, turn_up): physics.model must be "
        "'active_brownian'"
    )
    job = api.client.post("/jobs", json={**swimmers, "policy_from": source}).json()["id"]
    succeeds(api, api_settings, job)
    metrics = api.client.get(f"/jobs/{job}/metrics").json()
    assert metrics["work"]["decide_calls"] > 0 and len(metrics["worlds"]) == 3


def test_a_networks_cost_is_counted_when_sent_and_charged_to_each_job(api: Api) -> None:
    """What one observation costs is counted from the graph when the network is sent, shown,
    and charged to the work budget of every job that names it, decision by decision: a swarm
    that a small network decides for fits, the same swarm under a network of three layers of
    1,000 does not."""
    width, count = len(OBSERVATION), len(ACTIONS)
    small = network(api, models.mlp(width, count, hidden=16))
    shown = api.client.get(small["links"]["self"]).json()
    assert shown["multiply_adds"] == 16 * (width + 1) + 16 + count * (16 + 1)
    assert shown["live_bytes"] == 2 * 16 * 4
    heavy = network(api, models.dense_stack(width, count, units=1000, layers=3))
    counted = api.client.get(heavy["links"]["self"]).json()["multiply_adds"]
    assert 3_000_000 < counted < 4_000_000
    swarm = {
        "robots": {"count": 1000, "schedule": "simultaneous"},
        "learning": {"episodes": 0, "max_steps": 1000},
        "evaluation": {"worlds": 20},
    }
    fits = api.client.post("/jobs", json={**swarm, "policy_from": small["policy_from"]})
    assert fits.status_code == 202, fits.text
    problem = assert_problem(
        api.client.post("/jobs", json={**swarm, "policy_from": heavy["policy_from"]}), 422
    )
    pointers = [error["pointer"] for error in problem["errors"]]
    assert "#/policy_from" in pointers and "#/robots/count" in pointers
    assert {error["type"] for error in problem["errors"]} == {"budget_exceeded"}
    assert (
        f"for the network's decisions ({counted:,} multiply-adds an observation)"
        in (problem["detail"])
    )


def test_a_network_kept_before_costs_were_counted_is_checked_when_a_job_names_it(
    api: Api,
) -> None:
    """A network the store kept without a counted cost (sent to an earlier version) is checked
    in its sandbox when a job names it: counted and charged, or refused as it would be sent."""
    layout: dict[str, Any] = {"action_set": "behaviors", "communication": ("none",),
                               "observation": OBSERVATION, "actions": ACTIONS}  # fmt: skip
    kept = api.store.policies.add_network(
        model=models.mlp(len(OBSERVATION), len(ACTIONS)), **layout
    )
    assert api.client.get(f"/policies/{kept.id}").json()["multiply_adds"] is None
    accepted = api.client.post("/jobs", json={**EVALUATE, "policy_from": kept.policy_from})
    assert accepted.status_code == 202, accepted.text
    hostile = api.store.policies.add_network(
        model=models.integer_division(len(OBSERVATION)), **layout
    )
    pointer, rule, detail = refused(api, {**EVALUATE, "policy_from": hostile.policy_from}, "/jobs")
    assert (pointer, rule) == ("#/policy_from", "policy_unusable")
    assert "(Mod): Mod is not an operator a policy needs" in detail
