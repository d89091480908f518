"""NanoNav for Stable-Baselines3: ``NanoNavVecEnv``, many worlds of one robot stepped in one
compiled call, as SB3's own vectorised environments behave. Needs the ``rl`` extra
(``pip install 'nanonav[rl]'``).

A room of its own because SB3's ``VecEnv`` is not Gymnasium's ``VectorEnv``: SB3 resets a
finished world within the step that ended it, returns its last observation in
``infos[k]["terminal_observation"]``, marks a time limit in ``"TimeLimit.truncated"`` and takes
its seeds through ``seed()`` before ``reset()``. ``NanoNavVectorEnv`` keeps Gymnasium's
next-step reset; both step the same worlds (``nanonav.engine.worlds``).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import gymnasium
import numpy as np
from gymnasium import spaces
from numpy.typing import NDArray
from stable_baselines3.common.vec_env import VecEnv
from stable_baselines3.common.vec_env.base_vec_env import VecEnvIndices, VecEnvStepReturn

from nanonav.engine.observations import (
    action_labels,
    as_scenario,
    observation_of,
    state_labels,
    with_robots,
)
from nanonav.engine.worlds import Worlds
from nanonav.env.robot import ScenarioLike, action_space_of
from nanonav.scenario import Steering


class NanoNavVecEnv(VecEnv):
    """``num_envs`` worlds of one robot (as ``NanoNavEnv``), an SB3 ``VecEnv``.

    Observations are float32 (what SB3's policies and an exported ONNX model take), bounded as
    ``NanoNavEnv``'s; actions are the scenario's action set by number, each held for the
    scenario's decision interval (``learning.decision_interval_s`` in active_brownian), its
    rewards summed. ``seed(s)`` makes the next ``reset()`` draw world k from seed s + k (as
    ``NanoNavVectorEnv.reset(seed=s)``: the same worlds); without a seed, ``reset()`` draws
    the next worlds of each one's stream. Each info holds the world's tabular ``state``.
    ``steering="continuous"`` (active_brownian) takes ``NanoNavEnv``'s continuous turn, a
    ``Box`` (side, up) each -1 .. 1, for its action.
    """

    render_mode = None

    def __init__(
        self, num_envs: int = 1, scenario: ScenarioLike = None, *, steering: Steering = "discrete"
    ) -> None:
        if num_envs < 1:
            raise ValueError("num_envs must be at least 1")
        self.scenario = with_robots(as_scenario(scenario), 1)
        self._worlds = Worlds(self.scenario, num_envs, "simultaneous", steering=steering)
        self._seen = observation_of(self.scenario, steering)
        self.observation_labels = self._seen.labels
        self.action_labels = action_labels(self.scenario, steering)
        self.state_labels = state_labels(self.scenario)
        observations = spaces.Box(
            self._seen.low.astype(np.float32), self._seen.high.astype(np.float32),
            dtype=np.float32,
        )  # fmt: skip
        super().__init__(num_envs, observations, action_space_of(self._worlds))
        self._actions = self._worlds.blank_actions()
        self._all = np.ones(num_envs, dtype=np.bool_)
        self._none = np.zeros(num_envs, dtype=np.bool_)

    def reset(self) -> NDArray[np.float32]:
        seeds = self._seeds
        if all(s is not None for s in seeds):
            self._worlds.seed([int(s) for s in seeds if s is not None])
        self._worlds.step(None, self._all)
        self._reset_seeds()
        self._reset_options()
        self.reset_infos = [{"state": int(s)} for s in self._worlds.state[:, 0]]
        return self._observed()

    def step_async(self, actions: NDArray[Any]) -> None:
        shape = self._worlds.action_shape
        given = np.asarray(actions)
        if given.size == int(np.prod(shape)):
            given = given.reshape(shape)
        self._worlds.check(given, shape)
        self._actions[:] = given

    def step_wait(self) -> VecEnvStepReturn:
        w = self._worlds
        w.step(self._actions, self._none, checked=True)
        terminated = ~w.active[:, 0]
        truncated = w.over & ~terminated
        done = terminated | truncated
        observed = self._observed()
        rewards = w.reward[:, 0].astype(np.float32)
        infos: list[dict[str, Any]] = [
            {"state": int(state), "TimeLimit.truncated": bool(cut)}
            for state, cut in zip(w.state[:, 0], truncated, strict=True)
        ]
        if done.any():
            ended = np.flatnonzero(done)
            for k in ended:
                infos[k]["terminal_observation"] = observed[k].copy()
            w.redraw(done)
            fresh = self._observed()
            observed[ended] = fresh[ended]
            for k in ended:
                self.reset_infos[k] = {"state": int(w.state[k, 0])}
        return observed, rewards, done, infos

    def _observed(self) -> NDArray[np.float32]:
        observed: NDArray[np.float32] = self._worlds.obs[:, 0][:, self._seen.columns].astype(
            np.float32
        )
        return observed

    def close(self) -> None:
        """Nothing to release: the worlds are arrays of this process."""

    def get_attr(self, attr_name: str, indices: VecEnvIndices = None) -> list[Any]:
        """The attribute, once per world asked for: every world shares this object's."""
        return [getattr(self, attr_name) for _ in self._get_indices(indices)]

    def set_attr(self, attr_name: str, value: Any, indices: VecEnvIndices = None) -> None:
        """Set on this object, which every world shares."""
        setattr(self, attr_name, value)

    def env_method(
        self, method_name: str, *method_args: Any, indices: VecEnvIndices = None,
        **method_kwargs: Any,
    ) -> list[Any]:  # fmt: skip
        """This object's method, called once per world asked for."""
        method = getattr(self, method_name)
        return [method(*method_args, **method_kwargs) for _ in self._get_indices(indices)]

    def env_is_wrapped(
        self, wrapper_class: type[gymnasium.Wrapper[Any, Any, Any, Any]],
        indices: VecEnvIndices = None,
    ) -> list[bool]:  # fmt: skip
        """No world is wrapped: they are arrays, not Gymnasium environments."""
        return [False for _ in self._get_indices(indices)]


def _recurrent_logits_class() -> Any:
    import torch
    from stable_baselines3.common.policies import ActorCriticPolicy

    class RecurrentLogits(torch.nn.Module):
        """Recurrent PPO's actor for one step: observation and memory in, logits and memory
        out (what its ``get_distribution`` does at a step that starts no episode)."""

        def __init__(self, policy: Any) -> None:
            super().__init__()
            self.policy = policy  # a submodule: its weights are the graph's, not constants

        def forward(
            self, observation: torch.Tensor, hidden: torch.Tensor, cell: torch.Tensor
        ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
            p = self.policy
            # what get_distribution calls: the base class's, not the actor-critic's own
            features = super(ActorCriticPolicy, p).extract_features(  # type: ignore[misc]
                observation, p.pi_features_extractor
            )
            out, (hidden_out, cell_out) = p.lstm_actor(features.unsqueeze(0), (hidden, cell))
            logits = p.action_net(p.mlp_extractor.forward_actor(out.squeeze(0)))
            return logits, hidden_out, cell_out

    return RecurrentLogits


def _clipped_class() -> Any:
    import torch

    class Clipped(torch.nn.Module):
        """A continuous policy's greedy action: its mean, clipped to the ``Box``'s -1 .. 1 as
        SB3's ``predict`` clips it (the memory outputs of a recurrent one pass through)."""

        def __init__(self, head: torch.nn.Module) -> None:
            super().__init__()
            self.head = head

        def forward(self, *given: torch.Tensor) -> Any:
            out = self.head(*given)
            if isinstance(out, tuple):
                return (torch.clamp(out[0], -1.0, 1.0), *out[1:])
            return torch.clamp(out, -1.0, 1.0)

    return Clipped


def export_onnx(
    model: Any,
    path: Path,
    *,
    observation: Sequence[str] | None = None,
    actions: Sequence[str] | None = None,
) -> None:
    """Write ``model``'s greedy decision as ONNX, the exchange format of neural networks: one
    float32 input ``observation`` (batch x the env's observation width) and one output
    ``logits`` (batch x actions; the greedy action is its argmax). PPO gives its policy's
    action logits, DQN its Q-values. Recurrent PPO (sb3-contrib) carries its actor's LSTM
    memory as two more inputs, ``hidden_in`` and ``cell_in`` (layers x batch x units, zeros at
    an episode's start), given back as ``hidden_out`` and ``cell_out`` after the logits. The
    file is data, not code: onnxruntime runs it with no Python of the model's, unlike SB3's
    own zip, which holds pickles. A model trained on a continuous turn (``steering=
    "continuous"``) gives its greedy turn instead, ``turn`` (batch x 2: side, up, clipped to
    -1 .. 1).

    ``observation`` and ``actions`` (the env's ``observation_labels`` and ``action_labels``)
    are written into the model's metadata (``METADATA_OBSERVATION``, ``METADATA_ACTIONS``, as
    JSON lists), where ``POST /policies`` reads them when the request does not name them."""
    import torch
    from stable_baselines3 import DQN, PPO

    from nanonav.rl.export import write_onnx

    policy = model.policy
    head: torch.nn.Module
    if isinstance(model, PPO):

        class Logits(torch.nn.Module):
            def __init__(self, actor: Any) -> None:
                super().__init__()
                self.actor = actor  # a submodule: its weights are the graph's, not constants

            def forward(self, observation: torch.Tensor) -> torch.Tensor:
                actor = self.actor
                features = actor.extract_features(observation, actor.pi_features_extractor)
                logits: torch.Tensor = actor.action_net(actor.mlp_extractor.forward_actor(features))
                return logits

        head = Logits(policy)
    elif isinstance(model, DQN):
        head = policy.q_net
    elif type(model).__name__ == "RecurrentPPO":
        head = _recurrent_logits_class()(policy)
    else:
        raise ValueError(
            f"{type(model).__name__} cannot be exported: only PPO, recurrent PPO and DQN"
        )
    width = int(model.observation_space.shape[0])
    first = "logits"
    if isinstance(model.action_space, spaces.Box):
        head = _clipped_class()(head)
        first = "turn"
    head = head.to("cpu").eval()
    given: tuple[torch.Tensor, ...] = (torch.zeros(1, width),)
    inputs, outputs = ["observation"], [first]
    axes: dict[str, dict[int, str]] = {"observation": {0: "batch"}, first: {0: "batch"}}
    if type(model).__name__ == "RecurrentPPO":
        lstm = policy.lstm_actor
        memory = torch.zeros(lstm.num_layers, 1, lstm.hidden_size)
        given = (*given, memory, memory.clone())
        inputs += ["hidden_in", "cell_in"]
        outputs += ["hidden_out", "cell_out"]
        axes.update({name: {1: "batch"} for name in (*inputs[1:], *outputs[1:])})
    write_onnx(head, given, path, inputs=inputs, outputs=outputs, axes=axes,
               observation=observation, actions=actions)  # fmt: skip
