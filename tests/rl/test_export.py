"""The trainer's network as the service runs it: ONNX Runtime's answers are the network's own
(the greedy logits or turn, and a recurrent one's memory), at any batch, and the service's
check with its default limits accepts the file."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import onnxruntime as ort
import pytest
import torch

from nanonav.env.arrays import NanoNavArrayEnv
from nanonav.rl.export import export_network
from nanonav.rl.graph import MAX_LIVE_BYTES, MAX_MULTIPLY_ADDS
from nanonav.rl.networks import ActorCritic
from nanonav.rl.onnx_policy import Limits, check_model
from nanonav.scenario import Steering, preset_scenario
from nanonav.settings import Settings


def _trained(steering: Steering, memory_units: int) -> tuple[ActorCritic, NanoNavArrayEnv]:
    from nanonav.rl.ppo import PPO, PPOConfig

    world = preset_scenario("alonso-kirkegaard", seed=5000)
    env = NanoNavArrayEnv(8, world, steering=steering)
    config = PPOConfig(envs=8, rollout=16, minibatch=64, bptt=8, memory_units=memory_units)
    learner = PPO(env, config)
    learner.learn(config.batch)  # the normaliser's statistics are no longer 0 and 1
    return learner.net, env


@pytest.mark.parametrize("memory_units", [0, 25])
@pytest.mark.parametrize("steering", ["discrete", "continuous"])
def test_the_exported_network_decides_as_the_trained_one(
    steering: Steering, memory_units: int, tmp_path: Path
) -> None:
    net, env = _trained(steering, memory_units)
    path = tmp_path / "policy.onnx"
    export_network(net, path, observation=env.observation_labels, actions=env.action_labels)
    assert [p.name for p in tmp_path.iterdir()] == ["policy.onnx"]
    session = ort.InferenceSession(str(path), providers=["CPUExecutionProvider"])
    meta = session.get_modelmeta().custom_metadata_map
    assert json.loads(meta["nanonav.actions"]) == env.action_labels
    rows = np.random.default_rng(0).normal(size=(5, env.width)).astype(np.float32) * 3
    memory = np.random.default_rng(1).normal(size=(5, memory_units)).astype(np.float32)
    feeds = {"observation": rows} | ({"memory_in": memory} if memory_units else {})
    answers = session.run(None, feeds)
    with torch.no_grad():
        features, kept = net._features(torch.from_numpy(rows), torch.from_numpy(memory))
        head = net.actor(features).numpy()
    if steering == "continuous":
        np.testing.assert_allclose(answers[0], np.clip(head, -1.0, 1.0), atol=1e-5)
        assert session.get_outputs()[0].name == "turn"
    else:
        np.testing.assert_allclose(answers[0], head, atol=1e-5)
    if memory_units:
        assert [i.name for i in session.get_inputs()] == ["observation", "memory_in"]
        np.testing.assert_allclose(answers[1], kept.numpy(), atol=1e-5)
    settings = Settings()
    info = check_model(
        path.read_bytes(), env.width, env.actions, max_bytes=settings.policy_model_max_bytes,
        continuous=steering == "continuous", limits=Limits.of(settings),
    )  # fmt: skip
    assert len(info.memory) == (1 if memory_units else 0)
    assert 0 < info.cost.multiply_adds < MAX_MULTIPLY_ADDS
    assert 0 < info.cost.live_bytes < MAX_LIVE_BYTES
