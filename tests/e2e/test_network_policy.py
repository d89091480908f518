"""End to end: PPO trained for a thousand decisions through the SB3 VecEnv (``nanonav
train``), its exported ONNX model sent with ``nanonav policy``, and evaluated by a real
``python -m worker`` process through the API, exactly as the same model evaluated here."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from nanonav.cli import main
from nanonav.rl.evaluate import evaluate
from nanonav.rl.onnx_policy import NetworkPolicy
from nanonav.scenario import Scenario
from tests.conftest import Api
from tests.e2e.test_jobs import finished, submit, wait_for
from tests.processes import FIRST_JOB_S, Worker

pytestmark = pytest.mark.timeout(300)

TRAIN: dict[str, Any] = {
    "preset": "tumour-microswimmers",
    "physics": {"robot_radius_um": 2.0, "time_limit_s": 10.0},
}
TIMINGS = ("duration_s",)


def test_a_trained_network_is_sent_and_evaluated_by_a_worker(
    api: Api,
    start_worker: Callable[..., Worker],
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    scenario_file = tmp_path / "scenario.json"
    scenario_file.write_text(json.dumps(TRAIN))
    out = tmp_path / "ppo"
    train = ["train", "--scenario", str(scenario_file), "--seed", "5000", "--algo", "ppo",
             "--steps", "1024", "--envs", "4", "--rollout", "128", "--out", str(out),
             "--no-progress"]  # fmt: skip
    assert main(train) == 0
    assert main(["policy", str(out / "policy.onnx"), "--url", api.url]) == 0
    said = capsys.readouterr().out
    sent = "policy 1: policy_from 'policy-1' (a network: 3 observation columns -> 4 steering"
    assert sent + " actions)" in said

    start_worker()
    evaluated = {**TRAIN, "seed": 9000, "policy_from": "policy-1",
                 "learning": {"episodes": 0}, "evaluation": {"worlds": 4}}  # fmt: skip
    job_id = submit(api, evaluated)
    job, _ = wait_for(api, job_id, finished, FIRST_JOB_S)
    assert job["status"] == "succeeded", job
    metrics = api.client.get(f"/jobs/{job_id}/metrics").json()

    resolved = Scenario.model_validate(job["scenario"])
    model = (out / "policy.onnx").read_bytes()
    with NetworkPolicy(model, 3, 4, max_bytes=len(model)) as network:
        here = evaluate(resolved, network)
    assert [{k: v for k, v in w.items() if k not in TIMINGS} for w in metrics["worlds"]] == [
        {k: v for k, v in w.items() if k not in TIMINGS} for w in here.to_dict()["worlds"]
    ]
    assert api.client.get(f"/jobs/{job_id}/plots/trajectory.png").status_code == 200
