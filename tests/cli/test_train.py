"""``nanonav train``: NanoNav's own trainer (the default) trains PPO and recurrent PPO, prints
its progress, leaves a network the service accepts, a checkpoint a later run resumes from and
a report; with ``--library sb3`` each Stable-Baselines3 learner trains for a few hundred
decisions through the SB3 VecEnv and leaves its model, checkpoints, TensorBoard logs and a
report that can be read back."""

from __future__ import annotations

import json
import re
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import onnxruntime as ort
import pytest
import torch
from sb3_contrib import RecurrentPPO
from stable_baselines3 import DQN, PPO
from stable_baselines3.common.base_class import BaseAlgorithm

from nanonav.cli import main
from nanonav.env.baselines import NanoNavVecEnv
from nanonav.rl.graph import MAX_LIVE_BYTES, MAX_MULTIPLY_ADDS
from nanonav.rl.onnx_policy import Limits, check_model
from nanonav.settings import Settings

LOADERS: dict[str, type[BaseAlgorithm]] = {"ppo": PPO, "recurrent-ppo": RecurrentPPO, "dqn": DQN}


@pytest.mark.parametrize("algo", sorted(LOADERS))
def test_a_learner_of_sb3_trains_and_leaves_what_it_learned(
    algo: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / algo
    rollout = [] if algo == "dqn" else ["--rollout", "96", "--library", "sb3"]
    args = ["train", "--preset", "paper-single", "--seed", "5000", "--algo", algo,
            "--steps", "256", "--envs", "2", "--checkpoint-every", "128", "--out", str(out),
            "--no-progress", *rollout]  # fmt: skip
    # PPO and its recurrent kin collect --rollout decisions a world before each update, so
    # they run past --steps to the end of that rollout, and say how far (two worlds of 96:
    # 384; a default rollout of the recurrent learner, 2,048 a world, took 43 s of the suite)
    assert main(args) == 0
    report = json.loads((out / "training.json").read_text())
    assert report["algo"] == algo and report["envs"] == 2 and report["seed"] == 5000
    assert report["library"] == "sb3"
    assert report["decisions"] == (256 if algo == "dqn" else 384)
    assert report["decisions_per_s"] > 0
    assert f"trained {algo}" in capsys.readouterr().out
    kept = list((out / "checkpoints").iterdir())
    assert len(kept) >= 2 and all(p.suffix == ".zip" for p in kept)
    events = list((out / "tensorboard").rglob("events.out.tfevents.*"))
    assert events and all(e.stat().st_size > 0 for e in events)
    assert json.loads((out / "scenario.json").read_text())["seed"] == 5000
    model = LOADERS[algo].load(out / "model.zip", device="cpu")
    env = NanoNavVecEnv(2, {"preset": "paper-single", "seed": 9000})
    obs = env.reset()
    actions, _ = model.predict(obs, deterministic=True)
    assert np.asarray(actions).shape == (2,)
    assert all(0 <= a < len(env.action_labels) for a in np.asarray(actions))
    # the exported policy, run by onnxruntime, decides as the model does
    assert report["onnx"] == "policy.onnx"
    session = ort.InferenceSession(str(out / "policy.onnx"), providers=["CPUExecutionProvider"])
    given = session.get_inputs()
    assert given[0].name == "observation" and given[0].shape[1] == obs.shape[1]
    feeds = {"observation": obs}
    if algo == "recurrent-ppo":  # its memory in, at an episode's start: zeros
        assert [g.name for g in given[1:]] == ["hidden_in", "cell_in"]
        feeds |= {g.name: np.zeros((g.shape[0], 2, g.shape[2]), np.float32) for g in given[1:]}
    logits = session.run(["logits"], feeds)[0]
    assert logits.shape == (2, len(env.action_labels))
    np.testing.assert_array_equal(logits.argmax(axis=1), actions)
    # and the service's check passes it, its operators allowed and its cost under the caps
    passes_the_services_check(out / "policy.onnx", obs.shape[1], len(env.action_labels))


def passes_the_services_check(path: Path, width: int, actions: int, **options: bool) -> None:
    """What ``POST /policies`` checks, with the service's default limits."""
    data = path.read_bytes()
    settings = Settings()
    assert len(data) <= settings.policy_model_max_bytes
    assert 4 * len(data) / 3 < settings.max_body_bytes  # sent in base64
    info = check_model(data, width, actions, max_bytes=settings.policy_model_max_bytes,
                       limits=Limits.of(settings), **options)  # fmt: skip
    assert 0 < info.cost.multiply_adds < MAX_MULTIPLY_ADDS
    assert 0 < info.cost.live_bytes < MAX_LIVE_BYTES


def test_a_scenario_that_is_not_one_is_refused_naming_the_field(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({"robots": {"count": 0}}))
    args = ["train", "--scenario", str(bad), "--steps", "8", "--out", str(tmp_path / "out")]
    assert main(args) == 2
    assert "robots.count" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


def test_a_continuous_turn_is_trained_and_exported_as_a_turn(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "turn"
    swimmers = tmp_path / "swimmers.json"
    swimmers.write_text(json.dumps({"physics": {"time_limit_s": 2.0}}))
    args = ["train", "--preset", "tumour-microswimmers", "--scenario", str(swimmers),
            "--steering", "continuous", "--steps", "64", "--envs", "2", "--rollout", "32",
            "--out", str(out), "--no-progress"]  # fmt: skip
    assert main(args) == 0
    report = json.loads((out / "training.json").read_text())
    assert report["steering"] == "continuous" and report["library"] == "nanonav"
    session = ort.InferenceSession(str(out / "policy.onnx"), providers=["CPUExecutionProvider"])
    meta = session.get_modelmeta().custom_metadata_map
    assert json.loads(meta["nanonav.actions"]) == ["turn_side", "turn_up"]
    assert "gradient_side" in json.loads(meta["nanonav.observation"])
    width = session.get_inputs()[0].shape[1]
    turn = session.run(["turn"], {"observation": np.ones((3, width), np.float32)})[0]
    assert turn.shape == (3, 2) and np.all(np.abs(turn) <= 1.0)
    passes_the_services_check(out / "policy.onnx", width, 2, continuous=True)
    capsys.readouterr()
    for refused, says in (
        (["--algo", "dqn", "--preset", "tumour-microswimmers"], "dqn chooses among actions"),
        (["--preset", "paper-single"], "needs physics.model 'active_brownian'"),
    ):
        wrong = ["train", *refused, "--steering", "continuous", "--steps", "8", "--out",
                 str(tmp_path / "no")]  # fmt: skip
        assert main(wrong) == 2
        assert says in capsys.readouterr().err
    dqn = ["train", "--algo", "dqn", "--rollout", "8", "--preset", "paper-single", "--steps", "8",
           "--out", str(tmp_path / "no")]  # fmt: skip
    assert main(dqn) == 2
    assert "--rollout: dqn learns from a replay buffer" in capsys.readouterr().err
    assert not (tmp_path / "no").exists()


@pytest.mark.parametrize("algo", ["ppo", "recurrent-ppo"])
def test_nanonavs_trainer_is_the_default_and_says_how_fast_it_went(
    algo: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / algo
    args = ["train", "--preset", "alonso-kirkegaard", "--seed", "5000", "--algo", algo,
            "--envs", "16", "--rollout", "16", "--minibatch", "128", "--steps", "600",
            "--out", str(out)]  # fmt: skip
    assert main(args) == 0
    printed = capsys.readouterr().out
    # progress is printed as it goes, stdout being no terminal here: the last line at least
    assert re.search(r"^768/600 decisions  [\d,]+/s  ", printed, re.M), printed
    assert f"trained {algo} to 768 decisions" in printed
    report = json.loads((out / "training.json").read_text())
    assert report["library"] == "nanonav" and report["algo"] == algo
    assert report["decisions"] == report["decisions_this_run"] == 768  # three whole rollouts
    assert report["resumed_from"] is None
    assert report["decisions_per_s"] == pytest.approx(768 / report["seconds"], rel=0.01)
    assert report["threads"] == 1 and report["device"] == "cpu"
    assert report["memory_units"] == (25 if algo == "recurrent-ppo" else 0)
    assert report["peak_memory_mb"] > 0
    assert {"checkpoint.pt", "model.pt", "policy.onnx", "scenario.json"} <= {
        p.name for p in out.iterdir()
    }
    session = ort.InferenceSession(str(out / "policy.onnx"), providers=["CPUExecutionProvider"])
    names = [i.name for i in session.get_inputs()]
    assert names == (["observation", "memory_in"] if algo == "recurrent-ppo" else ["observation"])
    passes_the_services_check(out / "policy.onnx", 3, 4)


def test_a_run_resumes_from_its_checkpoints_decision_count(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "run"
    first = ["train", "--preset", "paper-single", "--seed", "5000", "--algo", "recurrent-ppo",
             "--envs", "8", "--rollout", "16", "--bptt", "8", "--minibatch", "64",
             "--steps", "256", "--out", str(out), "--no-progress"]  # fmt: skip
    assert main(first) == 0
    kept = torch.load(out / "checkpoint.pt", weights_only=True)
    assert kept["decisions"] == 256
    assert main(["train", "--resume", str(out), "--steps", "512", "--no-progress"]) == 0
    report = json.loads((out / "training.json").read_text())
    assert report["resumed_from"] == 256 and report["decisions"] == 512
    assert report["decisions_this_run"] == 256 and report["algo"] == "recurrent-ppo"
    assert report["config"]["bptt"] == 8 and report["memory_units"] == 25
    assert "trained recurrent-ppo to 512 decisions (from 256)" in capsys.readouterr().out
    assert torch.load(out / "checkpoint.pt", weights_only=True)["decisions"] == 512
    assert not list(out.glob("*.tmp"))


@pytest.mark.parametrize(
    ("args", "says"),
    [
        (["--resume", "RUN", "--preset", "paper-single"], "--preset: a resumed run keeps"),
        (["--resume", "RUN", "--memory-units", "8"], "--memory-units: a resumed run keeps"),
        (["--resume", "NOTHING"], "holds no run to resume"),
        (["--library", "sb3", "--memory", "gru", "--out", "X"], "NanoNav's trainer's, not"),
        (["--algo", "dqn", "--library", "nanonav", "--out", "X"], "Stable-Baselines3's"),
        (["--algo", "recurrent-ppo", "--memory", "none", "--out", "X"], "learns with a memory"),
        (["--memory-units", "8", "--out", "X"], "with a memory only"),
        (["--algo", "recurrent-ppo", "--rollout", "20", "--out", "X"], "whole sequences of 16"),
        (["--preset", "paper-single"], "--out DIR"),
    ],
)
def test_options_that_do_not_fit_are_refused(
    args: list[str], says: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    (tmp_path / "RUN").mkdir()
    (tmp_path / "RUN" / "checkpoint.pt").write_bytes(b"")
    (tmp_path / "RUN" / "scenario.json").write_text("{}")
    given = [str(tmp_path / a) if a in ("RUN", "NOTHING", "X") else a for a in args]
    assert main(["train", "--steps", "8", *given]) == 2
    assert says in capsys.readouterr().err
    assert not (tmp_path / "X").exists()


def test_progress_reaches_a_file_while_it_trains(tmp_path: Path) -> None:
    """``nanonav train ... > log``: lines of progress are in the file while the run goes on,
    not all at its end, each with the rate the summary gives the same way."""
    log = tmp_path / "train.log"
    with log.open("w") as out:
        process = subprocess.Popen(
            [sys.executable, "-m", "nanonav.cli", "train", "--preset", "alonso-kirkegaard",
             "--seed", "5000", "--envs", "64", "--rollout", "16", "--minibatch", "512",
             "--steps", "100000000", "--progress-every", "0.2", "--no-overlap",
             "--out", str(tmp_path / "run")],
            stdout=out, stderr=subprocess.PIPE, text=True,
        )  # fmt: skip
        try:
            deadline = time.monotonic() + 120
            lines: list[str] = []
            while len(lines) < 2:
                assert process.poll() is None, process.communicate()[1]
                assert time.monotonic() < deadline, "no progress written within two minutes"
                time.sleep(0.2)
                lines = [line for line in log.read_text().splitlines() if "decisions  " in line]
        finally:
            process.kill()
            process.communicate()
    assert re.match(r"^[\d,]+/100,000,000 decisions  [\d,]+/s  ", lines[0]), lines
