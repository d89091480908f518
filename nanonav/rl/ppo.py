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

import contextlib
import math
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np
import torch
from torch import Tensor

from nanonav.env.arrays import NanoNavArrayEnv
from nanonav.rl.collect import Collector, CollectorProcess, Ended, Rollout
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
    # the next rollout collected on a second core while the learner learns from the last
    # (its policy then one update behind); False: in turn, in one process
    overlap: bool = True

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
        given.setdefault("overlap", False)  # runs from before it learned in turn
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
    reached: int = 0  # of the episodes that ended, those that reached a cell


class PPO:
    """PPO over a ``NanoNavArrayEnv``'s worlds (``config.envs`` of them). ``learn`` runs whole
    rollouts until a number of decisions is done; ``state_dict`` and ``load_state_dict`` are
    what a checkpoint holds (the networks, the optimiser, every random stream, the
    decisions done). With ``config.overlap`` the rollouts are collected in a process of its
    own (``nanonav.rl.collect``), the next while the learner learns from the last: ``close``
    ends it (a ``with`` block does)."""

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
        self.shuffle = np.random.default_rng(config.seed)
        self.decisions = 0
        self.updates = 0
        # the streams live here until the collector's process starts, and there from then on;
        # that process decides on the CPU, whatever device the learner learns on
        self._collector = Collector(
            env, self.net, steps=config.rollout, bptt=config.bptt, gamma=config.gamma,
            seed=config.seed, device=torch.device("cpu") if config.overlap else self.device,
        )  # fmt: skip
        self._away: CollectorProcess | None = None
        # with overlap, the rollout collected for the next update: its slot in the collector's
        # two, the returns of the episodes that ended in it, and its seconds
        self._pending: tuple[int, Ended, float] | None = None
        self.collector_peak_memory_mb = 0.0  # the collector's process's, once it has ended
        self._rollout = Rollout.allocated(
            config.rollout, config.envs, env, config.memory_units, config.bptt, self.device
        )

    def __enter__(self) -> PPO:
        return self

    def __exit__(self, kind: type[BaseException] | None, *_: object) -> None:
        if kind is None:
            self.close()
        else:  # a run stopped or failed: its collector's streams are not wanted, only its end
            self.abandon()

    def abandon(self) -> None:
        """End the collector's process at once, a rollout under way or not (the streams it
        holds are lost: a stopped run takes up again from its last checkpoint)."""
        if self._away is not None:
            self._away.kill()
            self._pending = None
            self._away = None

    def close(self) -> None:
        """End the collector's process, if there is one."""
        if self._away is not None:
            state = None
            with contextlib.suppress(RuntimeError):
                state = self._away.state_dict()
            self._away.close()
            self._pending = None  # its rollout was in the memory the process shared
            self.collector_peak_memory_mb = self._away.peak_memory_mb
            self._away = None
            if state is not None:
                self._collector.load_state_dict(state)

    def prepare(self) -> None:
        """What a run counts as its start, not its training: with overlap, the collector's
        process started (it loads torch and the engine and draws its worlds); the engine's
        step loaded from numba's cache where the rollouts are collected."""
        if self.config.overlap:
            self._remote()
        else:
            self._collector.warm_up()

    def collector_pid(self) -> int | None:
        """The collector's process's id while there is one."""
        return None if self._away is None else self._away.pid

    def _remote(self) -> CollectorProcess:
        if self._away is None:
            c = self.config
            self._away = CollectorProcess(
                self.env, self.net, steps=c.rollout, bptt=c.bptt, gamma=c.gamma, seed=c.seed
            )
            self._away.load_state_dict(self._collector.state_dict())
        return self._away

    def learn(self, decisions: int, after: Callable[[Update], None] | None = None) -> None:
        """Collect rollouts and learn from each until ``decisions`` are done in all (the last
        rollout finished: a run does a whole number of them); ``after`` is told of each.
        With ``overlap`` it returns with the next rollout collected and none under way (a
        checkpoint may be read then), and the next call learns from that rollout first."""
        if self.config.overlap:
            self._learn_overlapped(decisions, after)
            return
        rollout = self._rollout
        while self.decisions < decisions:
            started = time.perf_counter()
            ended = self._collector.collect(rollout)
            collected = time.perf_counter()
            losses = self._update(rollout)
            self._learned(ended, losses, collected - started, time.perf_counter() - collected,
                          after)  # fmt: skip

    def _learn_overlapped(self, decisions: int, after: Callable[[Update], None] | None) -> None:
        """Rollout k+1 is collected, with the weights the update of rollout k starts from,
        while that update runs: each rollout's policy is one update behind the learner's
        (PPO's ratio to the policy that collected it corrects for that, as in asynchronous
        PPO). Only a run's first rollout is collected alone: each call returns with the next
        rollout collected, and the next call learns from it, so that a run learns the same,
        bit for bit, whether it stops for checkpoints or not."""
        left = math.ceil(max(decisions - self.decisions, 0) / self.config.batch)
        if left == 0:
            return
        away = self._remote()
        if self._pending is None:
            away.start(0, self.net)
            self._pending = (0, *away.wait())
        for _ in range(left):
            which, ended, collect_s = self._pending
            away.start(1 - which, self.net)
            started = time.perf_counter()
            losses = self._update(away.rollouts[which].to(self.device))
            update_s = time.perf_counter() - started
            self._learned(ended, losses, collect_s, update_s, after)
            self._pending = (1 - which, *away.wait())

    def _learned(self, ended: Ended, losses: tuple[float, float, float, float],
                 rollout_s: float, update_s: float,
                 after: Callable[[Update], None] | None) -> None:  # fmt: skip
        self.decisions += self.config.batch
        self.updates += 1
        returns = ended.returns
        if after is not None:
            after(Update(
                self.decisions, len(returns), float(np.mean(returns)) if returns else None,
                *losses, rollout_s, update_s, ended.reached,
            ))  # fmt: skip

    def _update(self, r: Rollout) -> tuple[float, float, float, float]:
        c, net = self.config, self.net
        advantages = gae(r.rewards, r.values, r.dones, r.next_value, c.gamma, c.gae_lambda)
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

                memory = pick(memories) if c.memory_units else memories[:0].reshape(0, 0)
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
            "shuffle_rng": self.shuffle.bit_generator.state,
            **(self._away or self._collector).state_dict(),
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
        self.shuffle.bit_generator.state = state["shuffle_rng"]
        self._collector.load_state_dict(state)
        if self._away is not None:
            self._away.load_state_dict(state)
        self._pending = None  # collected before the streams were taken up
        self.decisions = int(state["decisions"])
        self.updates = int(state["updates"])


def rollouts_for(decisions: int, config: PPOConfig) -> int:
    """How many rollouts reach ``decisions``: a run does whole ones."""
    return max(1, math.ceil(decisions / config.batch))
