"""The rollout: every world stepped with the networks' decisions until each has taken a rollout's
decisions, in the learner's own process or in a process of its own.

Why a process of its own: on two cores the update and the next rollout can run at once, each on
one core, when the rollout is collected with the weights of one update before (``PPOConfig.
overlap``). Python's threads cannot share the work: stepping the worlds and deciding are a few
hundred short calls a rollout that each hold the interpreter's lock. The collector's process
reads the weights and writes its rollouts in memory both processes map (two rollouts, so that
it fills one while the learner reads the other), and says what it did over a socket.

It is started as ``python -m nanonav.rl.collect``, not by ``multiprocessing``: its spawn runs
the caller's main script again in the child (a script without ``if __name__ == "__main__"``
would start a second run), and a fork copies whatever threads and locks the caller holds.
The files behind the shared memory are removed once both processes have mapped them, so that a
killed run leaves none behind.
"""

from __future__ import annotations

import pickle
import resource
import shutil
import socket
import subprocess
import sys
import tempfile
import time
import traceback
import weakref
from dataclasses import dataclass, fields
from multiprocessing.connection import Connection
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
import torch
from torch import Tensor

from nanonav.env.arrays import NanoNavArrayEnv
from nanonav.rl.networks import ActorCritic


@dataclass
class Rollout:
    """A rollout's tensors, ``(steps, worlds, ...)``, allocated once and filled in place; the
    value of each world's state after the last step is ``next_value``."""

    obs: Tensor
    actions: Tensor
    log_probs: Tensor
    values: Tensor
    rewards: Tensor
    dones: Tensor
    starts: Tensor
    memories: Tensor  # each sequence's first memory: (steps // bptt, worlds, units)
    next_value: Tensor

    @classmethod
    def allocated(
        cls, steps: int, worlds: int, env: NanoNavArrayEnv, memory_units: int, bptt: int,
        device: torch.device,
    ) -> Rollout:  # fmt: skip
        shape = (steps, worlds)
        action_shape = (*shape, env.actions) if env.continuous else shape
        sequences = steps // bptt if memory_units else 0
        return cls(
            obs=torch.zeros((*shape, env.width), device=device),
            actions=torch.zeros(action_shape, device=device),
            log_probs=torch.zeros(shape, device=device),
            values=torch.zeros(shape, device=device),
            rewards=torch.zeros(shape, device=device),
            dones=torch.zeros(shape, device=device),
            starts=torch.zeros(shape, dtype=torch.bool, device=device),
            memories=torch.zeros((sequences, worlds, memory_units), device=device),
            next_value=torch.zeros(worlds, device=device),
        )

    def tensors(self) -> list[Tensor]:
        return [getattr(self, f.name) for f in fields(self)]

    def to(self, device: torch.device) -> Rollout:
        return Rollout(*(tensor.to(device) for tensor in self.tensors()))


class Ended(NamedTuple):
    """The episodes that ended in a rollout: their returns, and how many of them reached a
    cell (the rest ran out of time)."""

    returns: list[float]
    reached: int


class Collector:
    """Steps ``env``'s worlds with ``net``'s decisions, ``steps`` decisions a world a rollout,
    carrying each world's observation, memory and episode from one rollout to the next. Its
    random streams (the sampling's and each world's) are what a checkpoint keeps of it."""

    def __init__(
        self, env: NanoNavArrayEnv, net: ActorCritic, *, steps: int, bptt: int, gamma: float,
        seed: int, device: torch.device,
    ) -> None:  # fmt: skip
        self.env = env
        self.net = net
        self.steps = steps
        self.bptt = bptt
        self.gamma = gamma
        self.device = device
        self.generator = torch.Generator(device).manual_seed(seed)
        self.obs: Tensor | None = None  # each world's observation now (None before it is drawn)
        self._memory = net.blank_memory(env.num_envs, device)
        self._starting = torch.ones(env.num_envs, dtype=torch.bool, device=device)
        self._returns = np.zeros(env.num_envs)

    def warm_up(self) -> None:
        """Step a world of one once, so that numba's machine code for the step is loaded (a
        few seconds) before a run's clock starts, and not in its first rollout."""
        one = NanoNavArrayEnv(1, self.env.scenario, steering=self.env.steering)
        one.reset()
        one.step(np.zeros((1, 2)) if one.continuous else np.zeros(1, dtype=np.int64))

    def collect(self, r: Rollout) -> Ended:
        """Fill ``r`` with the next rollout: what the episodes that ended in it did."""
        env, net, device = self.env, self.net, self.device
        recurrent = net.memory_units > 0
        if self.obs is None:
            self.obs = torch.from_numpy(env.reset()).to(device)
        obs, memory, starting = self.obs, self._memory, self._starting
        returns: list[float] = []
        reached = 0
        for t in range(self.steps):
            r.obs[t] = obs
            r.starts[t] = starting
            if recurrent:
                memory = memory * (~starting).unsqueeze(-1)
                if t % self.bptt == 0:
                    r.memories[t // self.bptt] = memory
            decision = net.act(obs, memory, self.generator)
            step = env.step(decision.action.cpu().numpy())
            reward = torch.from_numpy(step.reward).to(device)
            if step.final_obs.shape[0]:
                # a time limit is no end of the task: what would follow is the value's
                # (Stable-Baselines3's bootstrap), read with the memory after the decision
                cut = torch.from_numpy(np.flatnonzero(step.truncated)).to(device)
                final = torch.from_numpy(step.final_obs).to(device)
                reward[cut] += self.gamma * net.value(final, decision.memory[cut])
            done = step.terminated | step.truncated
            self._returns += step.reward
            if done.any():
                returns.extend(self._returns[done].tolist())
                reached += int(step.terminated.sum())
                self._returns[done] = 0.0
            r.actions[t] = decision.action
            r.log_probs[t] = decision.log_prob
            r.values[t] = decision.value
            r.rewards[t] = reward
            starting = torch.from_numpy(done).to(device)
            r.dones[t] = starting
            obs = torch.from_numpy(step.obs).to(device)
            memory = decision.memory
        self.obs, self._memory, self._starting = obs, memory, starting
        r.next_value.copy_(net.value(obs, memory * (~starting).unsqueeze(-1)))
        return Ended(returns, reached)

    def state_dict(self) -> dict[str, Any]:
        """The random streams: the sampling's, and each world's two generators with the seed
        they were drawn from."""
        return {
            "sampling_rng": self.generator.get_state(),
            "env_seed": self.env.seed,
            "env_rngs": self.env.generator_states(),
        }

    def load_state_dict(self, state: dict[str, Any]) -> None:
        """Take up the streams of ``state``: every world is drawn afresh from its generators as
        they were (an episode under way when they were kept is not resumed)."""
        self.generator.set_state(state["sampling_rng"])
        if state["env_rngs"]:  # none before the worlds were first drawn
            self.env.restore_generators(state["env_rngs"])
            self.env.seed = int(state["env_seed"])
        self.obs = None
        self._memory = self.net.blank_memory(self.env.num_envs, self.device)
        self._starting.fill_(True)
        self._returns[:] = 0.0


@dataclass(frozen=True)
class _Spec:
    """What the collector's process builds its worlds and its networks from."""

    worlds: int
    scenario_json: str
    steering: str
    net_kwargs: dict[str, Any]
    steps: int
    bptt: int
    gamma: float
    seed: int
    apart: bool


# where the shared tensors' files are made: memory, where the system has it as a folder
SHARED_FOLDER = Path("/dev/shm")
# the seconds the collector's process has to start (import torch and the engine, draw its worlds)
START_TIMEOUT_S = 300.0


def _mapped(folder: Path, name: str, like: Tensor) -> Tensor:
    """A tensor shaped and typed as ``like`` in the file ``folder/name``, mapped shared."""
    if like.numel() == 0:
        return torch.zeros_like(like)
    path = folder / name
    mapped = torch.from_file(str(path), shared=True, size=like.numel(), dtype=like.dtype)
    return mapped.view(like.shape)


def _mapped_rollouts(folder: Path, like: Rollout) -> tuple[Rollout, Rollout]:
    """The two rollouts both processes map, shaped as ``like``."""
    first, second = (
        Rollout(*(_mapped(folder, f"{k}-{f.name}", getattr(like, f.name)) for f in fields(like)))
        for k in range(2)
    )
    return first, second


def _mapped_weights(folder: Path, net: ActorCritic) -> dict[str, Tensor]:
    """A tensor both processes map for each of ``net``'s weights and buffers."""
    return {
        name: _mapped(folder, f"w-{name}", value.detach().cpu())
        for name, value in net.state_dict().items()
    }


def _send(conn: Connection, message: Any) -> None:
    """``message`` pickled by ``pickle`` itself: ``Connection.send`` pickles as
    ``multiprocessing`` does, which torch teaches to send a tensor as a handle that only a
    process ``multiprocessing`` started can open."""
    conn.send_bytes(pickle.dumps(message, protocol=pickle.HIGHEST_PROTOCOL))


def _receive(conn: Connection) -> Any:
    return pickle.loads(conn.recv_bytes())


class CollectorProcess:
    """A ``Collector`` in a process of its own: ``start(k, net)`` has it fill rollout k (of
    ``rollouts``, the two both processes map) with ``net``'s weights as they are then;
    ``wait`` gives what the episodes that ended in it did, and its seconds. Its streams
    are read and set (``state_dict``, ``load_state_dict``) when no rollout is under way."""

    def __init__(self, env: NanoNavArrayEnv, net: ActorCritic, *, steps: int, bptt: int,
                 gamma: float, seed: int) -> None:  # fmt: skip
        like = Rollout.allocated(steps, env.num_envs, env, net.memory_units, bptt,
                                 torch.device("cpu"))  # fmt: skip
        base = SHARED_FOLDER if SHARED_FOLDER.is_dir() else None
        folder = Path(tempfile.mkdtemp(prefix="nanonav-rollouts-", dir=base))
        try:
            self.rollouts = _mapped_rollouts(folder, like)
            self.weights = _mapped_weights(folder, net)
            spec = _Spec(
                env.num_envs, env.scenario.model_dump_json(), env.steering, net.arguments(),
                steps, bptt, gamma, seed, env.apart,
            )  # fmt: skip
            ours, theirs = socket.socketpair()
            self._process = subprocess.Popen(
                [sys.executable, "-m", "nanonav.rl.collect", str(theirs.fileno())],
                pass_fds=(theirs.fileno(),),
            )
            theirs.close()
            self._conn = Connection(ours.detach())
            # a learner dropped without ``close`` still ends its collector (at the socket's end)
            self._finalizer = weakref.finalize(self, _shut, self._conn, self._process)
            self.weights_from(net)
            # the child maps the files and builds its worlds; then no file is needed
            self._tell((spec, str(folder)))
            self._answer(timeout_s=START_TIMEOUT_S)
        except BaseException:
            self._stop()
            raise
        finally:
            shutil.rmtree(folder, ignore_errors=True)
        self._busy = False
        self.peak_memory_mb = 0.0

    def _ended(self) -> RuntimeError:
        try:
            code: int | None = self._process.wait(timeout=5)
        except subprocess.TimeoutExpired:
            code = None
        return RuntimeError(f"the collector's process ended (exit code {code})")

    def _tell(self, message: Any) -> None:
        try:
            _send(self._conn, message)
        except OSError:
            raise self._ended() from None

    def _answer(self, timeout_s: float | None = None) -> Any:
        if timeout_s is not None and not self._conn.poll(timeout_s):
            raise RuntimeError(f"the collector's process did not answer within {timeout_s:.0f} s")
        try:
            kind, value = _receive(self._conn)
        except (EOFError, OSError):
            raise self._ended() from None
        if kind == "error":
            raise RuntimeError(f"the collector's process failed:\n{value}")
        return value

    def _ask(self, kind: str, value: Any = None) -> Any:
        if self._busy:
            raise RuntimeError("a rollout is under way")
        self._tell((kind, value))
        return self._answer()

    @property
    def pid(self) -> int:
        return self._process.pid

    def weights_from(self, net: ActorCritic) -> None:
        for name, value in net.state_dict().items():
            self.weights[name].copy_(value)

    def start(self, which: int, net: ActorCritic) -> None:
        """Have rollout ``which`` filled with ``net``'s weights as they are now."""
        if self._busy:
            raise RuntimeError("a rollout is already under way")
        self.weights_from(net)
        self._tell(("collect", which))
        self._busy = True

    def wait(self) -> tuple[Ended, float]:
        """What the episodes that ended in the rollout under way did, and its seconds."""
        if not self._busy:
            raise RuntimeError("no rollout is under way")
        self._busy = False
        (returns, reached), seconds = self._answer()
        return Ended(list(returns), int(reached)), float(seconds)

    def state_dict(self) -> dict[str, Any]:
        state: dict[str, Any] = self._ask("state")
        return state

    def load_state_dict(self, state: dict[str, Any]) -> None:
        self._ask("restore", state)

    def close(self) -> None:
        """Stop the process, its peak memory kept in ``peak_memory_mb``."""
        try:
            if self._busy:
                self.wait()
            self.peak_memory_mb = float(self._ask("stop"))
        except (RuntimeError, OSError):
            pass
        self._stop()

    def kill(self) -> None:
        """Kill the process without waiting for a rollout under way."""
        process = getattr(self, "_process", None)
        if process is not None and process.poll() is None:
            process.kill()
        self._stop()

    def _stop(self) -> None:
        finalizer = getattr(self, "_finalizer", None)
        if finalizer is not None:
            finalizer()
        elif getattr(self, "_process", None) is not None:
            _shut(getattr(self, "_conn", None), self._process)


def _shut(conn: Connection | None, process: subprocess.Popen[bytes]) -> None:
    """Close the socket (the process ends at its end) and wait for the process, killing it
    after ten seconds."""
    if conn is not None:
        conn.close()
    try:
        process.wait(timeout=10)
    except subprocess.TimeoutExpired:
        process.kill()
        process.wait()


def _serve(conn: Connection) -> None:
    """The collector's process: one torch thread, its own worlds and networks, and a loop of
    requests until ``stop`` or the socket's end."""
    from nanonav.scenario import Scenario

    torch.set_num_threads(1)
    try:
        spec, folder = _receive(conn)
        scenario = Scenario.model_validate_json(spec.scenario_json)
        env = NanoNavArrayEnv(spec.worlds, scenario, steering=spec.steering, apart=spec.apart)
        net = ActorCritic(**spec.net_kwargs)
        like = Rollout.allocated(spec.steps, spec.worlds, env, net.memory_units, spec.bptt,
                                 torch.device("cpu"))  # fmt: skip
        rollouts = _mapped_rollouts(Path(folder), like)
        weights = _mapped_weights(Path(folder), net)
        net.load_state_dict(weights)
        collector = Collector(env, net, steps=spec.steps, bptt=spec.bptt, gamma=spec.gamma,
                              seed=spec.seed, device=torch.device("cpu"))  # fmt: skip
        collector.warm_up()
        _send(conn, ("ok", None))
    except Exception:
        _send(conn, ("error", traceback.format_exc()))
        return
    while True:
        try:
            kind, value = _receive(conn)
        except (EOFError, OSError):
            return
        try:
            if kind == "collect":
                began = time.perf_counter()
                net.load_state_dict(weights)
                ended = collector.collect(rollouts[value])
                _send(conn, ("ok", (tuple(ended), time.perf_counter() - began)))
            elif kind == "state":
                _send(conn, ("ok", collector.state_dict()))
            elif kind == "restore":
                collector.load_state_dict(value)
                _send(conn, ("ok", None))
            else:
                peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
                _send(conn, ("ok", peak))
                return
        except Exception:
            _send(conn, ("error", traceback.format_exc()))


if __name__ == "__main__":
    _serve(Connection(int(sys.argv[1])))
