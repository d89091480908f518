"""NanoNav's own PPO trainer, for thousands of worlds at once: one batched forward a decision
over every world, the rollout kept as tensors shaped ``(steps, worlds, ...)``, large
minibatches, and with a memory the GRU state carried per world and learned by truncated
backpropagation through time. As CleanRL's ``ppo.py`` and ``ppo_atari_lstm.py`` (one config,
GAE as a pure function), sized as Alonso & Kirkegaard's recurrent PPO can be.

Why our own: at the same settings Stable-Baselines3's PPO, sb3-contrib's RecurrentPPO and
TorchRL's did not reach the rate NanoNav's question needs (docs/explanation/speed.md has the
table and the command that measured it).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np
import torch
from torch import Tensor

from nanonav.env.arrays import NanoNavArrayEnv
from nanonav.rl.networks import ACTIVATIONS, Activation, ActorCritic

CHECKPOINT_FORMAT = 1


@dataclass(frozen=True)
class PPOConfig:
    """What a run learns with; the defaults are the fast settings (measured in
    ``benchmarks/train_speed.py``)."""

    envs: int = 1024  # worlds stepped together, one robot each
    rollout: int = 64  # decisions each world takes between two updates
    epochs: int = 4  # passes over a rollout
    minibatch: int = 8192  # decisions a gradient step
    learning_rate: float = 3e-4  # Adam's
    gamma: float = 0.99  # discount a decision
    gae_lambda: float = 0.95  # GAE's lambda
    clip: float = 0.2  # the surrogate's clip on the probability ratio
    entropy: float = 0.01  # the entropy bonus's weight
    value_weight: float = 0.5  # the value loss's weight
    max_grad_norm: float = 0.5  # the gradient's norm is cut to this
    memory_units: int = 0  # units of a GRU memory; 0: none (an MLP)
    bptt: int = 16  # decisions a sequence carries gradients through (with a memory)
    layers: tuple[int, ...] = (64, 64)  # hidden layers the actor and the critic share
    actor: tuple[int, ...] = ()  # the actor's own hidden layers, after the shared ones
    critic: tuple[int, ...] = ()  # the critic's own hidden layers
    activation: Activation = "relu"  # between hidden layers (tanh costs 4 ns a number here)
    seed: int = 0  # the weights', the sampling's and the shuffling's

    def __post_init__(self) -> None:
        if min(self.envs, self.rollout, self.epochs, self.minibatch, self.bptt) < 1:
            raise ValueError("envs, rollout, epochs, minibatch and bptt must be at least 1")
        if self.memory_units and self.rollout % self.bptt:
            raise ValueError(f"a rollout of {self.rollout} is not whole sequences of {self.bptt}")
        if self.activation not in ACTIVATIONS:
            raise ValueError(f"activation {self.activation!r} is not one of {ACTIVATIONS}")

    @property
    def batch(self) -> int:
        """Decisions a rollout collects."""
        return self.envs * self.rollout

    def to_json(self) -> dict[str, Any]:
        return asdict(self)

    @classmethod
    def of_json(cls, data: dict[str, Any]) -> PPOConfig:
        given = dict(data)
        for name in ("layers", "actor", "critic"):
            given[name] = tuple(given[name])
        return cls(**given)


def gae(
    rewards: Tensor, values: Tensor, dones: Tensor, next_value: Tensor, gamma: float,
    lam: float,
) -> Tensor:  # fmt: skip
    """Generalised advantage estimates (Schulman et al. 2016) of a rollout shaped ``(steps,
    worlds)``: ``dones[t]`` says an episode ended at step t (the value after it is of a new
    one, so nothing is carried across), ``next_value`` is the value of each world's state
    after the last step."""
    advantages = torch.zeros_like(rewards)
    carried = torch.zeros_like(next_value)
    for t in reversed(range(rewards.shape[0])):
        after = next_value if t == rewards.shape[0] - 1 else values[t + 1]
        going = 1.0 - dones[t]
        delta = rewards[t] + gamma * after * going - values[t]
        carried = delta + gamma * lam * going * carried
        advantages[t] = carried
    return advantages


@dataclass(frozen=True)
class Update:
    """What one rollout and its update did: the decisions done in all, the episodes that
    ended in the rollout and their mean return (None if none ended), the losses averaged
    over the update's gradient steps, and the seconds spent stepping and learning."""

    decisions: int
    episodes: int
    mean_return: float | None
    policy_loss: float
    value_loss: float
    entropy: float
    approx_kl: float
    rollout_s: float
    update_s: float


@dataclass
class _Rollout:
    """The rollout's tensors, ``(steps, worlds, ...)``, allocated once."""

    obs: Tensor
    actions: Tensor
    log_probs: Tensor
    values: Tensor
    rewards: Tensor
    dones: Tensor
    starts: Tensor
    memories: Tensor  # each sequence's first memory: (steps // bptt, worlds, units)
    returns: list[float] = field(default_factory=list)


class PPO:
    """PPO over a ``NanoNavArrayEnv``'s worlds (``config.envs`` of them). ``learn`` runs whole
    rollouts until a number of decisions is done; ``state_dict`` and ``load_state_dict`` are
    what a checkpoint holds (the networks, the optimiser, every random stream, the
    decisions done)."""

    def __init__(
        self, env: NanoNavArrayEnv, config: PPOConfig, *, device: str | torch.device = "cpu"
    ) -> None:
        if env.num_envs != config.envs:
            raise ValueError(f"the env has {env.num_envs} worlds, the config {config.envs}")
        self.env = env
        self.config = config
        self.device = torch.device(device)
        torch.manual_seed(config.seed)
        self.net = ActorCritic(
            env.width, env.actions, continuous=env.continuous, memory_units=config.memory_units,
            layers=config.layers, actor=config.actor, critic=config.critic,
            activation=config.activation,
        ).to(self.device)  # fmt: skip
        self.optimizer = torch.optim.Adam(self.net.parameters(), lr=config.learning_rate, eps=1e-5)
        self.generator = torch.Generator(self.device).manual_seed(config.seed)
        self.shuffle = np.random.default_rng(config.seed)
        self.decisions = 0
        self.updates = 0
        self._rollout = self._allocated()
        self._obs: Tensor | None = None
        self._memory = self.net.blank_memory(config.envs, self.device)
        self._starting = torch.ones(config.envs, dtype=torch.bool, device=self.device)
        self._returns = np.zeros(config.envs)

    def _allocated(self) -> _Rollout:
        c, n, d = self.config, self.config.envs, self.device
        shape = (c.rollout, n)
        action_shape = (*shape, self.env.actions) if self.env.continuous else shape
        sequences = c.rollout // c.bptt if c.memory_units else 0
        return _Rollout(
            obs=torch.zeros((*shape, self.env.width), device=d),
            actions=torch.zeros(action_shape, device=d),
            log_probs=torch.zeros(shape, device=d),
            values=torch.zeros(shape, device=d),
            rewards=torch.zeros(shape, device=d),
            dones=torch.zeros(shape, device=d),
            starts=torch.zeros(shape, dtype=torch.bool, device=d),
            memories=torch.zeros((sequences, n, c.memory_units), device=d),
        )

    def learn(self, decisions: int, after: Callable[[Update], None] | None = None) -> None:
        """Collect rollouts and learn from each until ``decisions`` are done in all (the last
        rollout finished: a run does a whole number of them); ``after`` is told of each."""
        while self.decisions < decisions:
            started = time.perf_counter()
            self._collect()
            collected = time.perf_counter()
            losses = self._update()
            self.decisions += self.config.batch
            self.updates += 1
            returns = self._rollout.returns
            if after is not None:
                after(Update(
                    self.decisions, len(returns),
                    float(np.mean(returns)) if returns else None, *losses,
                    collected - started, time.perf_counter() - collected,
                ))  # fmt: skip

    def _collect(self) -> None:
        c, r, env, net = self.config, self._rollout, self.env, self.net
        if self._obs is None:
            self._obs = torch.from_numpy(env.reset()).to(self.device)
        obs, memory, starting = self._obs, self._memory, self._starting
        r.returns = []
        for t in range(c.rollout):
            r.obs[t] = obs
            r.starts[t] = starting
            if c.memory_units:
                memory = memory * (~starting).unsqueeze(-1)
                if t % c.bptt == 0:
                    r.memories[t // c.bptt] = memory
            decision = net.act(obs, memory, self.generator)
            step = env.step(decision.action.cpu().numpy())
            reward = torch.from_numpy(step.reward).to(self.device)
            if step.final_obs.shape[0]:
                # a time limit is no end of the task: what would follow is the value's
                # (Stable-Baselines3's bootstrap), read with the memory after the decision
                cut = torch.from_numpy(np.flatnonzero(step.truncated)).to(self.device)
                final = torch.from_numpy(step.final_obs).to(self.device)
                reward[cut] += c.gamma * net.value(final, decision.memory[cut])
            done = step.terminated | step.truncated
            self._returns += step.reward
            if done.any():
                r.returns.extend(self._returns[done].tolist())
                self._returns[done] = 0.0
            r.actions[t] = decision.action
            r.log_probs[t] = decision.log_prob
            r.values[t] = decision.value
            r.rewards[t] = reward
            starting = torch.from_numpy(done).to(self.device)
            r.dones[t] = starting
            obs = torch.from_numpy(step.obs).to(self.device)
            memory = decision.memory
        self._obs, self._memory, self._starting = obs, memory, starting

    def _update(self) -> tuple[float, float, float, float]:
        c, r, net = self.config, self._rollout, self.net
        assert self._obs is not None
        kept = self._memory * (~self._starting).unsqueeze(-1)
        next_value = net.value(self._obs, kept)
        advantages = gae(r.rewards, r.values, r.dones, next_value, c.gamma, c.gae_lambda)
        returns = advantages + r.values
        # sequences of bptt decisions (one decision each without memory), shaped (sequences,
        # decisions, ...): sequence s = chunk x worlds + world, as the memories are kept
        length = c.bptt if c.memory_units else 1

        def sequences(x: Tensor) -> Tensor:
            chunks = x.reshape(c.rollout // length, length, c.envs, *x.shape[2:])
            return chunks.transpose(1, 2).reshape(-1, length, *x.shape[2:])

        obs, actions, log_probs = sequences(r.obs), sequences(r.actions), sequences(r.log_probs)
        starts, advantages, returns = sequences(r.starts), sequences(advantages), sequences(returns)
        memories = r.memories.reshape(-1, c.memory_units) if c.memory_units else r.memories
        count = obs.shape[0]
        per_minibatch = max(1, c.minibatch // length)
        totals = np.zeros(4)
        steps = 0
        for _ in range(c.epochs):
            order = torch.from_numpy(self.shuffle.permutation(count)).to(self.device)
            for at in range(0, count, per_minibatch):
                chosen = order[at : at + per_minibatch]

                def pick(x: Tensor, chosen: Tensor = chosen) -> Tensor:
                    return x.index_select(0, chosen)

                memory = pick(memories) if c.memory_units else self._memory[:0]
                judged = net.evaluate(pick(obs), pick(actions), memory, pick(starts))
                advantage = pick(advantages).reshape(-1)
                advantage = (advantage - advantage.mean()) / (advantage.std() + 1e-8)
                log_ratio = judged.log_prob - pick(log_probs).reshape(-1)
                ratio = log_ratio.exp()
                policy_loss = -torch.min(
                    ratio * advantage, torch.clamp(ratio, 1.0 - c.clip, 1.0 + c.clip) * advantage
                ).mean()
                value_loss = 0.5 * (judged.value - pick(returns).reshape(-1)).pow(2).mean()
                entropy = judged.entropy.mean()
                loss = policy_loss + c.value_weight * value_loss - c.entropy * entropy
                self.optimizer.zero_grad(set_to_none=True)
                torch.autograd.backward(loss)
                torch.nn.utils.clip_grad_norm_(net.parameters(), c.max_grad_norm)
                self.optimizer.step()
                with torch.no_grad():
                    approx_kl = ((ratio - 1.0) - log_ratio).mean()
                    totals += torch.stack([policy_loss, value_loss, entropy, approx_kl]).numpy()
                steps += 1
        net.normaliser.update(r.obs)
        mean = totals / max(steps, 1)
        return float(mean[0]), float(mean[1]), float(mean[2]), float(mean[3])

    def state_dict(self) -> dict[str, Any]:
        """Everything a resumed run needs: the config, the decisions and updates done, the
        networks, the optimiser, and every random stream (torch's global one, the sampling's,
        the shuffling's, and each world's two generators)."""
        return {
            "format": CHECKPOINT_FORMAT,
            "config": self.config.to_json(),
            "decisions": self.decisions,
            "updates": self.updates,
            "net": self.net.state_dict(),
            "optimizer": self.optimizer.state_dict(),
            "torch_rng": torch.get_rng_state(),
            "sampling_rng": self.generator.get_state(),
            "shuffle_rng": self.shuffle.bit_generator.state,
            "env_seed": self.env.seed,
            "env_rngs": self.env.generator_states(),
        }

    def load_state_dict(self, state: dict[str, Any]) -> None:
        """Take up a checkpoint's run where it stopped: every world is drawn afresh from its
        generators as they were (an episode under way when it was written is not resumed)."""
        if state.get("format") != CHECKPOINT_FORMAT:
            raise ValueError(
                f"a checkpoint of format {state.get('format')!r}, not {CHECKPOINT_FORMAT}"
            )
        if PPOConfig.of_json(state["config"]) != self.config:
            raise ValueError("the checkpoint was written with other settings")
        self.net.load_state_dict(state["net"])
        self.optimizer.load_state_dict(state["optimizer"])
        torch.set_rng_state(state["torch_rng"])
        self.generator.set_state(state["sampling_rng"])
        self.shuffle.bit_generator.state = state["shuffle_rng"]
        self.env.restore_generators(state["env_rngs"])
        self.env.seed = int(state["env_seed"])
        self.decisions = int(state["decisions"])
        self.updates = int(state["updates"])
        self._obs = None
        self._memory = self.net.blank_memory(self.config.envs, self.device)
        self._starting.fill_(True)
        self._returns[:] = 0.0


def rollouts_for(decisions: int, config: PPOConfig) -> int:
    """How many rollouts reach ``decisions``: a run does whole ones."""
    return max(1, math.ceil(decisions / config.batch))
