"""``nanonav policy``, ``policies``, ``fetch --policy`` and ``delete --policy`` against a real API
process and a real worker process: a job's table fetched, sent as a policy and evaluated; a
table trained through the environment sent from an ``.npz``; what a file may lack, refused by
name before anything is sent."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest

from nanonav.cli import main
from nanonav.client import Client
from nanonav.env import NanoNavEnv
from tests.client.test_client import TINY
from tests.conftest import LiveApi

pytestmark = pytest.mark.timeout(180)
WAIT_S = 60.0


def sent_policy(out: str) -> tuple[int, str]:
    found = re.match(r"policy (\d+): policy_from '(policy-\d+)' \(", out)
    assert found, out
    return int(found.group(1)), found.group(2)


def test_a_fetched_jobs_table_is_sent_listed_evaluated_fetched_and_deleted(
    live_api: LiveApi, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    url = ["--url", live_api.url]
    with Client(live_api.url, timeout=10) as client:
        job = client.wait(client.submit({**TINY, "seed": 31}).id, poll_s=0.05, timeout_s=WAIT_S)
        assert job.status == "succeeded"
        assert main(["fetch", str(job.id), "--out", str(tmp_path / "job"), *url]) == 0
        capsys.readouterr()
        code = main(["policy", str(tmp_path / "job" / "qtable.json"), "--name", "job 31", *url])
        out, err = capsys.readouterr()
        assert code == 0, err
        policy_id, policy_from = sent_policy(out)
        assert out.endswith("(behaviors actions, 72 states x 4 actions)\n")
        sent = client.policy(policy_id)
        assert sent.values == client.qtable(job.id)["values"]
        assert sent.name == "job 31"

        # evaluated through nanonav submit, whose Table 1 names it by its name and kind
        scenario = tmp_path / "evaluate.json"
        scenario.write_text(json.dumps(
            {**TINY, "seed": 31, "learning": {"episodes": 0, "max_steps": 60},
             "policy_from": policy_from}
        ))  # fmt: skip
        assert main(["submit", str(scenario), "--wait", *url]) == 0
        heading = capsys.readouterr().out.splitlines()[2]
        assert f'{policy_from} "job 31", a table sent, 0 training episodes' in heading, heading

        assert main(["policies", "--limit", "5", *url]) == 0
        listed = capsys.readouterr().out.splitlines()
        assert listed[0].split() == [
            "id", "policy_from", "name", "actions", "communication", "policy", "created"
        ]  # fmt: skip
        assert listed[2].split()[:5] == [str(policy_id), policy_from, "job", "31", "behaviors"]
        assert listed[2].split()[5:7] == ["none", "72x4"]

        assert main(["fetch", "--policy", str(policy_id), "--out", str(tmp_path / "p"), *url]) == 0
        capsys.readouterr()
        fetched = json.loads((tmp_path / "p" / "policy.json").read_text())
        assert fetched["id"] == policy_id and fetched["values"] == sent.values
        assert main(["policy", str(tmp_path / "p" / "policy.json"), *url]) == 0
        again, _ = sent_policy(capsys.readouterr().out)
        assert client.policy(again).values == sent.values
        assert client.policy(again).name == "job 31", "the name policy.json carries"

        code = main(["delete", "--policy", str(policy_id), *url])
        assert (code, capsys.readouterr().out) == (0, f"Deleted policy {policy_id}\n")
        assert main(["delete", "--policy", str(policy_id), *url]) == 2
        assert capsys.readouterr().err == (
            f"nanonav delete: 404 Policy not found: there is no policy {policy_id}\n"
        )


def test_a_table_trained_through_the_env_is_sent_from_an_npz(
    live_api: LiveApi, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    env = NanoNavEnv({"preset": "paper-single", "learning": {"actions": "directions"}})
    values = np.random.default_rng(3).normal(size=(len(env.state_labels), len(env.action_labels)))
    path = tmp_path / "trained.npz"
    np.savez(path, states=env.state_labels, actions=env.action_labels, values=values)
    key = ["--idempotency-key", "trained-3", "--url", live_api.url]
    assert main(["policy", str(path), *key]) == 0
    policy_id, _ = sent_policy(capsys.readouterr().out)
    assert main(["policy", str(path), *key]) == 0
    assert sent_policy(capsys.readouterr().out)[0] == policy_id, "the key gives it back"
    with Client(live_api.url, timeout=10) as client:
        sent = client.policy(policy_id)
    assert sent.name == "trained" and sent.action_set == "directions"
    assert np.array_equal(np.asarray(sent.values), values)


def test_a_file_that_holds_no_table_is_refused_before_anything_is_sent(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    nowhere = ["--url", "http://127.0.0.1:9"]  # nothing is sent: nothing needs to answer
    baseline = tmp_path / "qtable.json"
    baseline.write_text(json.dumps({"states": [], "actions": [], "values": [], "greedy": []}))
    labels_only = tmp_path / "labels.json"
    labels_only.write_text(json.dumps({"states": ["a"], "actions": ["b"]}))
    no_values = tmp_path / "partial.npz"
    np.savez(no_values, states=np.array(["a"]), actions=np.array(["b"]))
    not_npz = tmp_path / "text.npz"
    not_npz.write_text("not a zip")
    cases = [
        (baseline, "no states: a policy that learns no table has none to send"),
        (labels_only, "neither values nor greedy: no table to send"),
        (tmp_path / "missing.json", "cannot read"),
        (no_values, "no array values (it has states, actions)"),
        (not_npz, "cannot read"),
    ]
    for path, words in cases:
        assert main(["policy", str(path), *nowhere]) == 2, path
        err = capsys.readouterr().err
        assert err.startswith("nanonav policy: ") and words in err, err
    assert main(["delete", "3", "--policy", "4", *nowhere]) == 2
    assert "one of them" in capsys.readouterr().err


def test_a_network_nanonav_train_wrote_is_named_by_its_run_not_policy(tmp_path: Path) -> None:
    from nanonav.cli.policies import network_name

    run = tmp_path / "gru-1um"
    run.mkdir()
    (run / "training.json").write_text(json.dumps({"algo": "recurrent-ppo",
                                                   "decisions": 10_027_008}))  # fmt: skip
    assert network_name(run / "policy.onnx") == "gru-1um: recurrent-ppo, 10,027,008 decisions"
    (run / "training.json").write_text("{not json")
    assert network_name(run / "policy.onnx") == "policy"
    assert network_name(tmp_path / "mine.onnx") == "mine"  # no run beside it: the stem
