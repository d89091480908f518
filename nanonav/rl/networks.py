"""The networks NanoNav's trainer learns (``nanonav.rl.ppo``): an actor and a critic over the
observation, normalised by its running statistics, with an optional recurrent memory (a GRU
torso both read, as Alonso & Kirkegaard's recurrent policy has), and the greedy decision they
export as ONNX (``nanonav.rl.export``).

Each call takes every world at once: the rollout asks for one batched forward a decision
(``act``), the update for one a minibatch (``evaluate``), a recurrent one stepping its memory
through each minibatch's sequences (``nanonav.rl.gru``).
"""

from __future__ import annotations

import math
from typing import Any, Literal, NamedTuple

import torch
from torch import Tensor, nn

from nanonav.rl.gru import gru_sequence

Activation = Literal["relu", "tanh"]
ACTIVATIONS: tuple[Activation, ...] = ("relu", "tanh")
# An observation column further than this many standard deviations from its mean is cut there
OBSERVATION_CLIP = 10.0
LOG_2PI = math.log(2.0 * math.pi)


class Decision(NamedTuple):
    """What the rollout keeps of one decision of every world (no gradient)."""

    action: Tensor
    log_prob: Tensor
    value: Tensor
    memory: Tensor


class Judged(NamedTuple):
    """What the update needs of a minibatch's decisions under the current weights."""

    log_prob: Tensor
    entropy: Tensor
    value: Tensor


class Normaliser(nn.Module):
    """The observation's running mean and variance (buffers, so that they are saved with the
    weights and exported with them): columns in physical units differ by orders of
    magnitude (a count of molecules beside a distance in µm). Updated between two updates
    only, so that the rollout and the update that learns from it see the same inputs."""

    mean: Tensor
    var: Tensor
    count: Tensor

    def __init__(self, width: int) -> None:
        super().__init__()
        self.register_buffer("mean", torch.zeros(width))
        self.register_buffer("var", torch.ones(width))
        self.register_buffer("count", torch.zeros((), dtype=torch.float64))

    def forward(self, obs: Tensor) -> Tensor:
        scaled = (obs - self.mean) / torch.sqrt(self.var + 1e-8)
        return torch.clamp(scaled, -OBSERVATION_CLIP, OBSERVATION_CLIP)

    @torch.no_grad()
    def update(self, rows: Tensor) -> None:
        """Merge the statistics of ``rows`` (any leading axes) into the running ones (Chan,
        Golub and LeVeque's pairwise update)."""
        flat = rows.reshape(-1, rows.shape[-1]).to(torch.float64)
        n = float(flat.shape[0])
        if n == 0:
            return
        mean, var = flat.mean(0), flat.var(0, unbiased=False)
        seen = float(self.count)
        total = seen + n
        delta = mean - self.mean.double()
        merged_mean = self.mean.double() + delta * (n / total)
        merged = (self.var.double() * seen + var * n + delta**2 * (seen * n / total)) / total
        self.mean.copy_(merged_mean.float())
        self.var.copy_(merged.float())
        self.count.fill_(total)


def _hidden(inputs: int, layers: tuple[int, ...], activation: Activation) -> nn.Sequential:
    """Dense layers, each followed by ``activation``, initialised orthogonally (gain sqrt(2),
    as CleanRL's and the anchor's are)."""
    parts: list[nn.Module] = []
    width = inputs
    for units in layers:
        parts += [_orthogonal(nn.Linear(width, units), math.sqrt(2.0)), _activation(activation)]
        width = units
    return nn.Sequential(*parts)


def _mlp(inputs: int, layers: tuple[int, ...], outputs: int, activation: Activation,
         last_gain: float) -> nn.Sequential:  # fmt: skip
    """``_hidden`` layers, then a dense output initialised with ``last_gain`` (small for the
    actor, so that the first policy is near uniform)."""
    hidden = _hidden(inputs, layers, activation)
    width = layers[-1] if layers else inputs
    return nn.Sequential(*hidden, _orthogonal(nn.Linear(width, outputs), last_gain))


def _orthogonal(layer: nn.Linear, gain: float) -> nn.Linear:
    nn.init.orthogonal_(layer.weight, gain)
    nn.init.zeros_(layer.bias)
    return layer


def _activation(name: Activation) -> nn.Module:
    return nn.Tanh() if name == "tanh" else nn.ReLU()


class ActorCritic(nn.Module):
    """A torso both heads read, then the actor (action logits, or a turn's mean with a
    learned spread) and the critic (the value), each with ``actor`` and ``critic`` hidden
    layers of its own. The torso: with ``memory_units`` a GRU of that many units reads the
    normalised observation (its state is the robot's memory, carried from decision to
    decision and zeroed at an episode's start); then the shared hidden ``layers``.
    Alonso & Kirkegaard's recurrent policy is ``memory_units=25, layers=(), actor=(64, 64),
    critic=(128, 128)``; CleanRL's ``layers=(), actor=(64, 64), critic=(64, 64)``."""

    def __init__(
        self,
        width: int,
        actions: int,
        *,
        continuous: bool = False,
        memory_units: int = 0,
        layers: tuple[int, ...] = (64, 64),
        actor: tuple[int, ...] = (),
        critic: tuple[int, ...] = (),
        activation: Activation = "relu",
    ) -> None:
        super().__init__()
        self._arguments = {
            "width": width, "actions": actions, "continuous": continuous,
            "memory_units": memory_units, "layers": layers, "actor": actor, "critic": critic,
            "activation": activation,
        }  # fmt: skip
        self.width = width
        self.actions = actions
        self.continuous = continuous
        self.memory_units = memory_units
        self.normaliser = Normaliser(width)
        self.memory = nn.GRUCell(width, memory_units) if memory_units else None
        features = memory_units or width
        self.torso = _hidden(features, layers, activation)
        features = layers[-1] if layers else features
        self.actor = _mlp(features, actor, actions, activation, 0.01)
        self.critic = _mlp(features, critic, 1, activation, 1.0)
        self.log_std = nn.Parameter(torch.zeros(actions)) if continuous else None

    def arguments(self) -> dict[str, Any]:
        """What this network was built with: ``ActorCritic(**net.arguments())`` is another of
        the same shape (the collector's process builds its own so)."""
        return dict(self._arguments)

    def blank_memory(self, rows: int, device: torch.device | None = None) -> Tensor:
        """The memory of ``rows`` robots at an episode's start (an empty one without memory)."""
        return torch.zeros(rows, self.memory_units, device=device)

    def _features(self, obs: Tensor, memory: Tensor) -> tuple[Tensor, Tensor]:
        x = self.normaliser(obs)
        if self.memory is None:
            return self.torso(x), memory
        memory = self.memory(x, memory)
        return self.torso(memory), memory

    def _log_prob(self, head: Tensor, action: Tensor) -> tuple[Tensor, Tensor]:
        """The log-probability of ``action`` under the actor's output ``head``, and the
        distribution's entropy."""
        if self.log_std is not None:
            std = self.log_std.exp()
            z = (action - head) / std
            log_prob = (-0.5 * z * z - self.log_std - 0.5 * LOG_2PI).sum(-1)
            entropy = (0.5 + 0.5 * LOG_2PI + self.log_std).sum().expand_as(log_prob)
            return log_prob, entropy
        # as log_softmax, which on a few actions a row took 2.6x as long here (MKL's path for
        # a short last axis), backward included
        log_p = head - torch.logsumexp(head, dim=-1, keepdim=True)
        entropy = -(log_p.exp() * log_p).sum(-1)
        return log_p.gather(-1, action.long().unsqueeze(-1)).squeeze(-1), entropy

    @torch.no_grad()
    def act(self, obs: Tensor, memory: Tensor, generator: torch.Generator) -> Decision:
        """Sample each world's decision (its log-probability, the value, the next memory)."""
        features, memory = self._features(obs, memory)
        head = self.actor(features)
        if self.log_std is not None:
            noise = torch.randn(head.shape, generator=generator, device=head.device)
            action = head + self.log_std.exp() * noise
        else:
            uniform = torch.rand(head.shape, generator=generator, device=head.device)
            gumbel = -torch.log(-torch.log(uniform.clamp_(1e-12, 1.0 - 1e-7)))
            action = torch.argmax(head + gumbel, dim=-1)
        log_prob, _ = self._log_prob(head, action)
        return Decision(action, log_prob, self.critic(features).squeeze(-1), memory)

    @torch.no_grad()
    def value(self, obs: Tensor, memory: Tensor) -> Tensor:
        """The value of ``obs`` seen with ``memory`` (a truncated episode's last observation)."""
        features, _ = self._features(obs, memory)
        value: Tensor = self.critic(features).squeeze(-1)
        return value

    def evaluate(self, obs: Tensor, action: Tensor, memory: Tensor, starts: Tensor) -> Judged:
        """Judge a minibatch of sequences: ``obs`` shaped ``(sequences, steps, width)``, the
        memory each sequence began with, and where an episode started (the memory zeroed
        there before the step); the answers are flat, sequence by sequence. Without memory a
        sequence is one decision."""
        if self.memory is None:
            features = self.normaliser(obs.reshape(-1, self.width))
        else:
            steps = gru_sequence(self.memory, self.normaliser(obs), memory, starts)
            features = steps.reshape(-1, self.memory_units)
        features = self.torso(features)
        head = self.actor(features)
        flat = action.reshape(-1, self.actions) if self.continuous else action.reshape(-1)
        log_prob, entropy = self._log_prob(head, flat)
        return Judged(log_prob, entropy, self.critic(features).squeeze(-1))


class Greedy(nn.Module):
    """The greedy decision of an ``ActorCritic``, as the service runs it: the action logits
    (their argmax the action), or steering continuously the turn's mean clipped to -1 .. 1;
    a recurrent one takes its memory ``(batch, units)`` after the observation and gives it
    back after the decision (``nanonav.rl.graph``'s convention). Its GRU is a one-step
    ``nn.GRU`` holding the cell's weights, which exports as ONNX's GRU operator."""

    def __init__(self, net: ActorCritic) -> None:
        super().__init__()
        self.normaliser = net.normaliser
        self.torso = net.torso
        self.actor = net.actor
        self.continuous = net.continuous
        self.gru: nn.GRU | None = None
        if net.memory is not None:
            self.gru = nn.GRU(net.width, net.memory_units)
            with torch.no_grad():
                for name in ("weight_ih", "weight_hh", "bias_ih", "bias_hh"):
                    getattr(self.gru, f"{name}_l0").copy_(getattr(net.memory, name))

    def forward(self, obs: Tensor, *memory: Tensor) -> Tensor | tuple[Tensor, Tensor]:
        x = self.normaliser(obs)
        if self.gru is None:
            return self._decided(self.actor(self.torso(x)))
        _, h = self.gru(x.unsqueeze(0), memory[0].unsqueeze(0))
        h = h.squeeze(0)
        return self._decided(self.actor(self.torso(h))), h

    def _decided(self, head: Tensor) -> Tensor:
        return torch.clamp(head, -1.0, 1.0) if self.continuous else head
