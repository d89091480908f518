"""Networks an attacker with a key sends, against a real API process and a real worker process:
every hostile model is refused with a 422 naming its node or its field, and the API answers
/healthz after each; a network whose process crashes or hangs while a job evaluates it fails
that job with the reason, and the next job, another key's, succeeds on the same worker; a
cancel acts within a call."""

from __future__ import annotations

import base64
import os
import signal
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import httpx
import pytest

from nanonav.engine.observations import action_labels, observation_of
from nanonav.scenario import Scenario
from nanonav.store.migrate import upgrade
from tests.conftest import SCRIPTED, sqlite_url_in
from tests.processes import ApiServer, Worker, sandbox_of
from tests.rl import models

pytestmark = pytest.mark.timeout(300)
ALICE, BOB = "alice-0123456789abcdef0123456789ab", "bob-0123456789abcdef0123456789abcd"
OBSERVATION = list(observation_of(Scenario()).labels)
ACTIONS = action_labels(Scenario())
WIDTH, COUNT = len(OBSERVATION), len(ACTIONS)
# A network job that runs for many seconds: 100 robots deciding every step, one call a step,
# each too slow to reach a cell in the 50,000 steps (at the default speed, the network's
# behaviours brought every robot to the cell within a second on some seeds)
LONG: dict[str, Any] = {
    "seed": 7,
    "robots": {"count": 100, "schedule": "simultaneous", "speed": 0.001},
    "learning": {"episodes": 0, "max_steps": 50_000},
    "evaluation": {"worlds": 1},
}
SHORT: dict[str, Any] = {
    "preset": "paper-single",
    "learning": {"episodes": 2, "max_steps": 50},
    "evaluation": {"worlds": 1},
}
CALL_LIMIT_S = 4.0


@dataclass
class Deployment:
    api: ApiServer
    worker: Worker
    alice: httpx.Client
    bob: httpx.Client


def keyed(url: str, key: str) -> httpx.Client:
    headers = {**SCRIPTED, "Authorization": f"Bearer {key}"}
    return httpx.Client(base_url=url, timeout=60, headers=headers)


# A file in the API's working folder, as its SQLite database is in ``make run``'s
SECRET = b"SQLite format 3\x00 and every key's jobs"


@pytest.fixture
def deployment(tmp_path: Path) -> Iterator[Deployment]:
    url = sqlite_url_in(tmp_path)
    upgrade(url)
    keys = f"{ALICE},{BOB}"
    beside = tmp_path / "api"
    (beside / "var").mkdir(parents=True)
    (beside / "var" / "nanonav.db").write_bytes(SECRET)
    api = ApiServer(url, tmp_path / "api.log", cwd=beside, NANONAV_API_KEYS=keys)
    worker = Worker(url, tmp_path / "worker.log", NANONAV_NETWORK_CALL_LIMIT_S=str(CALL_LIMIT_S))
    try:
        api.wait_ready()
        worker.wait_ready()
        with keyed(api.url, ALICE) as alice, keyed(api.url, BOB) as bob:
            yield Deployment(api, worker, alice, bob)
    finally:
        api.terminate()
        worker.terminate()


def sent(client: httpx.Client, model: bytes, **labels: Any) -> httpx.Response:
    body = {"onnx": base64.b64encode(model).decode(), "observation": OBSERVATION,
            "actions": ACTIONS, **labels}  # fmt: skip
    return client.post("/policies", json=body)


HOSTILE: list[tuple[str, bytes, dict[str, Any], str, str]] = [
    ("SIGFPE on any observation", models.integer_division(WIDTH), {}, "#/onnx",
     "(Mod): Mod is not an operator a policy needs"),
    ("SIGFPE once an observation is positive",
     models.integer_division(WIDTH, only_when_positive=True), {}, "#/onnx",
     "(Mod): Mod is not an operator a policy needs"),
    ("twenty 99 x 99 convolutions", models.convolutions(WIDTH, COUNT), {}, "#/onnx",
     "(Expand): Expand is not an operator a policy needs"),
    ("forty values kept alive, summed", models.kept_alive(WIDTH, COUNT), {}, "#/onnx",
     "(Sum): Sum is not an operator a policy needs"),
    ("forty values kept alive, added", models.kept_alive(WIDTH, COUNT, summed_by="Add"), {},
     "#/onnx", "bytes an observation at once here (the cap on a policy's memory)"),
    ("four layers of 1,100", models.dense_stack(WIDTH, COUNT, units=1100, layers=4), {},
     "#/onnx", "multiply-adds an observation by here (the cap on a policy's cost)"),
    ("a loop of 10^12", models.looping(WIDTH, COUNT), {}, "#/onnx",
     "(Loop): Loop is not an operator a policy needs"),
    ("actions 3,297 and -3,296", models.far_actions(WIDTH), {}, "#/onnx",
     "answers an action outside 0..3 for a zero observation"),
    ("an observation no scenario gives", models.mlp(3, COUNT),
     {"observation": ["reading", "reading_change", "gradient_x"]}, "#/observation",
     "no scenario's robots observe (reading, reading_change, gradient_x)"),
]  # fmt: skip


def test_a_model_that_reads_a_file_beside_the_api_is_refused_without_its_bytes(
    deployment: Deployment,
) -> None:
    """The audit's model: a constant whose data is ``var/nanonav.db``, relative to the API's
    folder, gathered as the action, in each place such data can hide (one deployment for all:
    each costs an API's and a worker's start). The refusal names the node and quotes no byte
    of the file."""
    for form in ("sparse", "dense", "nested", "initializer"):
        model = models.file_reader(WIDTH, COUNT, "var/nanonav.db", form=form)
        answer = sent(deployment.alice, model, actions=ACTIONS)
        assert answer.status_code == 422, (form, answer.text)
        [error] = answer.json()["errors"]
        assert error["pointer"] == "#/onnx" and error["type"] == "policy_model", (form, error)
        assert "keeps its data outside the model" in error["detail"], (form, error)
        for leaked in (SECRET[:8].decode(), str(int.from_bytes(SECRET[:8], "little"))):
            assert leaked not in answer.text, form


def test_a_model_that_lies_about_its_shapes_is_refused_naming_its_reshape(
    deployment: Deployment,
) -> None:
    """The audit's lie: declared (1, K), (K, K) at run time. Its count would have been
    K; it is refused, since the graph alone does not fix the Reshape's size."""
    answer = sent(deployment.alice, models.shape_liar(WIDTH, COUNT, wide=4096))
    assert answer.status_code == 422, answer.text
    [error] = answer.json()["errors"]
    assert error["detail"].startswith(
        "node 'lying' (Reshape): it gives 'column', whose size the graph does not fix"
    ), error


def test_every_hostile_model_is_refused_and_the_api_answers_after_each(
    deployment: Deployment,
) -> None:
    for what, model, labels, pointer, detail in HOSTILE:
        started = time.monotonic()
        answer = sent(deployment.alice, model, **labels)
        assert answer.status_code == 422, (what, answer.text)
        [error] = answer.json()["errors"]
        assert error["pointer"] == pointer and detail in error["detail"], (what, error)
        assert time.monotonic() - started < 30, what
        assert deployment.alice.get("/healthz").status_code == 200, what
    assert deployment.api.process.poll() is None
    assert deployment.alice.get("/policies").json()["policies"] == []


def deciding(client: httpx.Client, job: int, timeout: float = 120.0) -> None:
    """Until the job's network decides: the job runs and has made progress."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        found: dict[str, Any] = client.get(f"/jobs/{job}").json()
        if found["status"] == "running" and found["progress"]["fraction"] > 0:
            return
        time.sleep(0.05)
    raise AssertionError(f"job {job} never decided: {found}")


def until_done(client: httpx.Client, job: int, timeout: float = 120.0) -> dict[str, Any]:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        found: dict[str, Any] = client.get(f"/jobs/{job}").json()
        if found["status"] in ("succeeded", "failed", "cancelled"):
            return found
        time.sleep(0.05)
    raise AssertionError(f"job {job} did not finish: {found}")


def queued(client: httpx.Client, scenario: dict[str, Any]) -> int:
    answer = client.post("/jobs", json=scenario)
    assert answer.status_code == 202, answer.text
    job: int = answer.json()["id"]
    return job


def test_a_network_that_crashes_or_hangs_fails_its_job_and_the_worker_goes_on(
    deployment: Deployment,
) -> None:
    answer = sent(deployment.alice, models.mlp(WIDTH, COUNT))
    assert answer.status_code == 201, answer.text
    network = {**LONG, "policy_from": answer.json()["policy_from"]}
    worker = deployment.worker.process.pid
    faults = [
        (signal.SIGFPE, "the network's process was killed by SIGFPE for one call of 100 "
         "observations: the model crashes ONNX Runtime"),
        (signal.SIGSTOP, f"the network took longer than {CALL_LIMIT_S:g} s for one call of 100 "
         "observations: its process was stopped"),
    ]  # fmt: skip
    for fault, reason in faults:
        crashing = queued(deployment.alice, network)
        behind = queued(deployment.bob, SHORT)
        deciding(deployment.alice, crashing)
        os.kill(sandbox_of(deployment.worker.process.pid), fault)
        failed = until_done(deployment.alice, crashing)
        assert failed["status"] == "failed" and failed["error"] == (
            f"policy_from: the policy raised SandboxFailed: {reason}"
        ), failed
        done = until_done(deployment.bob, behind)
        assert done["status"] == "succeeded" and done["attempts"] == 1, done
        assert deployment.worker.process.pid == worker and deployment.worker.process.poll() is None
    assert deployment.alice.get("/healthz").status_code == 200


def test_a_cancel_acts_within_a_call_that_does_not_end(deployment: Deployment) -> None:
    answer = sent(deployment.alice, models.mlp(WIDTH, COUNT))
    network = {**LONG, "policy_from": answer.json()["policy_from"]}
    job = queued(deployment.alice, network)
    behind = queued(deployment.bob, SHORT)
    deciding(deployment.alice, job)
    os.kill(
        sandbox_of(deployment.worker.process.pid), signal.SIGSTOP
    )  # a call that would never end
    started = time.monotonic()
    assert deployment.alice.post(f"/jobs/{job}/cancel").status_code == 200
    stopped = until_done(deployment.alice, job)
    assert stopped["status"] == "cancelled", stopped
    assert time.monotonic() - started < CALL_LIMIT_S  # before the call's own limit
    assert until_done(deployment.bob, behind)["status"] == "succeeded"
