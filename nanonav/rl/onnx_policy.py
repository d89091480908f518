"""Networks sent as ONNX models: checked before they are kept, and run to decide for robots,
each in a sandboxed process of its own (``nanonav.rl.sandbox``).

The check reads the graph (``nanonav.rl.graph``: allowed operators, shapes, the counted cost)
and then runs the model on a trial batch of observations (zeros, ones, and drawn ones), whose
answers must be what a policy gives: finite logits or turns, or actions of the action set.
Every answer of every later call is checked the same way, where it is made.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from nanonav.rl.graph import CALL_ROWS, InvalidModel, ModelInfo
from nanonav.rl.sandbox import Interrupted, Sandbox, SandboxFailed
from nanonav.rl.stops import Stopped
from nanonav.scenario import Steering
from nanonav.settings import Settings

# Observations a single inference call takes at most; a model's counted cost may allow fewer
INFERENCE_ROWS = CALL_ROWS
# Wall-clock seconds the process may take to start and check a model (its CPU limit ends it
# sooner if it computes; this one ends a process that waits)
LOAD_LIMIT_S = 60.0
# Extra CPU seconds an evaluation's process has besides the job's time limit: its start
START_CPU_S = 30.0


@dataclass(frozen=True)
class Limits:
    """What a network's process may take (``nanonav.settings``: the ``network_*`` fields)."""

    memory_bytes: int = 1_073_741_824
    check_cpu_s: float = 20.0
    call_s: float = 30.0
    run_cpu_s: float = 3600.0 + START_CPU_S

    @classmethod
    def of(cls, settings: Settings) -> Limits:
        return cls(
            memory_bytes=settings.network_memory_bytes,
            check_cpu_s=settings.network_check_cpu_s,
            call_s=settings.network_call_limit_s,
            run_cpu_s=settings.job_time_limit_s + START_CPU_S,
        )


def trial_observations(width: int) -> NDArray[np.float32]:
    """The observations a model answers before it is kept: two rows of zeros (more than one,
    so that a fixed batch of one is found out), ones, minus ones, and rows drawn from a normal
    distribution of scale 1 and 10 (a fixed draw)."""
    drawn = np.random.default_rng(0).normal(size=(4, width))
    drawn[2:] *= 10
    rows = [np.zeros((2, width)), np.ones((1, width)), -np.ones((1, width)), drawn]
    return np.concatenate(rows).astype(np.float32)


def _described(row: NDArray[np.float32]) -> str:
    if not row.any():
        return "a zero observation"
    shown = ", ".join(f"{x:.3g}" for x in row[:9])
    return f"the observation ({shown}{', ...' if row.size > 9 else ''})"


def checked_answer(
    answer: NDArray[Any], rows: NDArray[np.float32], info: ModelInfo, actions: int
) -> NDArray[Any]:
    """What a model answered for ``rows``, as the engine takes it (int64 actions, float64
    turns, float logits), or ``ValueError`` saying what is wrong: a shape that is not one
    answer a row, numbers that are not finite, an action outside the action set."""
    count = rows.shape[0]
    if info.output in ("logits", "turn"):
        what = "turns" if info.output == "turn" else "logits"
        if answer.dtype.kind != "f" or answer.shape != (count, actions):
            raise ValueError(
                f"the model answered {answer.dtype} of shape {list(answer.shape)} for {count} "
                f"observations: {what} are (batch, {actions}) floats"
            )
        bad = np.flatnonzero(~np.isfinite(answer).all(axis=1))
        if bad.size:
            raise ValueError(f"the model's {what} for {_described(rows[bad[0]])} are not finite")
        return answer
    if answer.dtype.kind not in "iu" or answer.shape not in ((count,), (count, 1)):
        raise ValueError(
            f"the model answered {answer.dtype} of shape {list(answer.shape)} for {count} "
            "observations: actions are (batch,) or (batch, 1) integers"
        )
    chosen = answer.reshape(-1).astype(np.int64)
    bad = np.flatnonzero((chosen < 0) | (chosen >= actions))
    if bad.size:
        # the action itself is not quoted: what a model computes is not echoed back to the
        # person who sent it, beyond what names the fault
        raise ValueError(
            f"the model answers an action outside 0..{actions - 1} for {_described(rows[bad[0]])}"
        )
    return chosen


def _loaded(
    box: Sandbox, data: bytes, width: int, actions: int, *, max_bytes: int, continuous: bool,
    keep_going: Callable[[], bool] | None = None,
) -> ModelInfo:  # fmt: skip
    """Check and load ``data`` in ``box``, then run it on the trial observations;
    ``InvalidModel`` saying why it cannot decide, a crash or an overrun of its process too;
    ``Stopped`` as soon as ``keep_going`` answers False."""
    try:
        info = box.load(data, width, actions, continuous=continuous, max_bytes=max_bytes,
                        limit_s=LOAD_LIMIT_S, keep_going=keep_going)  # fmt: skip
        rows = trial_observations(width)
        memory = [m.zeros(rows.shape[0]) for m in info.memory]
        answer = box.run([rows, *memory], limit_s=LOAD_LIMIT_S, keep_going=keep_going)
    except SandboxFailed as error:
        raise InvalidModel(str(error)) from None
    except Interrupted:
        raise Stopped("stopped while the network was checked") from None
    try:
        checked_answer(answer[0], rows, info, actions)
    except ValueError as error:
        raise InvalidModel(f"{error} (a trial run)") from None
    if len(answer) != 1 + len(info.memory):
        raise InvalidModel(f"the model gave {len(answer)} outputs, not {1 + len(info.memory)}")
    for m, kept in zip(info.memory, answer[1:], strict=True):
        if kept.shape != m.zeros(rows.shape[0]).shape or kept.dtype != np.float32:
            raise InvalidModel(
                f"the model's output {m.output_name!r} is not shaped as its memory "
                f"{m.input_name!r}, {list(m.dims)}"
            )
    return info


def check_model(
    data: bytes, width: int, actions: int, *, max_bytes: int, continuous: bool = False,
    limits: Limits | None = None,
) -> ModelInfo:  # fmt: skip
    """Check that ``data`` is an ONNX model that decides from ``width`` observation columns
    among ``actions`` actions, or ``continuous``ly a turn of ``actions`` parts, within the
    caps on its cost (``InvalidModel`` saying what is wrong if not), by reading its graph and
    running it on the trial observations, in a sandboxed process within ``limits``."""
    with ModelCheck(data, max_bytes=max_bytes, limits=limits) as check:
        return check.check(width, actions, continuous=continuous)


class ModelCheck:
    """A sent model's check, in one sandboxed process: first the labels its metadata names
    (``labels``), then, once the caller knows what it must decide among, the model itself
    (``check``). Nothing of the model is parsed in the caller's process."""

    def __init__(self, data: bytes, *, max_bytes: int, limits: Limits | None = None) -> None:
        if len(data) > max_bytes:
            raise InvalidModel(f"the model takes {len(data)} bytes, over the limit of {max_bytes}")
        self.data = data
        self.max_bytes = max_bytes
        limits = limits or Limits()
        self._box = Sandbox(memory_bytes=limits.memory_bytes, cpu_s=limits.check_cpu_s)

    def __enter__(self) -> ModelCheck:
        return self

    def __exit__(self, *_: object) -> None:
        self._box.close()

    def labels(self) -> tuple[list[str] | None, list[str] | None]:
        """The observation and action labels the model's metadata names (None where none);
        ``InvalidModel`` for a model that is none, or names labels that are not."""
        try:
            return self._box.labels(self.data, max_bytes=self.max_bytes, limit_s=LOAD_LIMIT_S)
        except SandboxFailed as error:
            raise InvalidModel(str(error)) from None

    def check(self, width: int, actions: int, *, continuous: bool = False) -> ModelInfo:
        """As ``check_model``, in this check's process."""
        return _loaded(
            self._box, self.data, width, actions, max_bytes=self.max_bytes, continuous=continuous
        )


def _along(memory: Any, part: slice) -> tuple[slice, ...]:
    """The index of rows ``part`` of a memory, along its batch axis."""
    return tuple(
        part if axis == memory.batch_axis else slice(None) for axis in range(len(memory.dims))
    )


class NetworkPolicy:
    """A checked model in its own process, deciding for many robots in one inference call (in
    parts of ``ModelInfo.cost.rows_per_call`` for more). ``keep_going`` is asked while a call
    runs: False stops it (``stops.Stopped``). Close it (or use it in a ``with``) to end
    its process."""

    def __init__(
        self,
        data: bytes,
        width: int,
        actions: int,
        *,
        max_bytes: int,
        continuous: bool = False,
        limits: Limits | None = None,
        keep_going: Callable[[], bool] | None = None,
    ) -> None:
        self.limits = limits or Limits()
        self._box = Sandbox(memory_bytes=self.limits.memory_bytes, cpu_s=self.limits.run_cpu_s)
        try:
            self.info = _loaded(
                self._box, data, width, actions, max_bytes=max_bytes, continuous=continuous,
                keep_going=keep_going,
            )  # fmt: skip
        except BaseException:
            self._box.close()
            raise
        self.width = width
        self.actions = actions
        self.keep_going = keep_going
        self._kept: list[NDArray[np.float32]] | None = None

    def __enter__(self) -> NetworkPolicy:
        return self

    def __exit__(self, *_: object) -> None:
        self.close()

    def close(self) -> None:
        """End the network's process."""
        self._box.close()

    @property
    def cpu_s(self) -> float:
        """CPU seconds the network's process has taken, its start included."""
        return self._box.cpu_used_s

    @property
    def remembers(self) -> bool:
        """Whether the network carries a memory from decision to decision (recurrent)."""
        return bool(self.info.memory)

    @property
    def steering(self) -> Steering:
        """``continuous`` where the network answers a turn (rows x parts of floats), else
        ``discrete`` (an action number a row)."""
        return "continuous" if self.info.output == "turn" else "discrete"

    def forget(self) -> None:
        """Start every robot's memory afresh at the next call (a new set of episodes)."""
        self._kept = None

    def __call__(self, observations: NDArray[np.float64]) -> NDArray[Any]:
        """The action of each row of ``observations`` (a continuous network's turn, a row of
        floats); a recurrent network's row k carries the memory row k had at the last call (the
        same robot, call after call, until ``forget``). ``ValueError`` for an answer that is
        not one, ``SandboxFailed`` for a process that died or overran."""
        rows = np.ascontiguousarray(observations, dtype=np.float32)
        memory = self.info.memory
        count = rows.shape[0]
        if memory and (self._kept is None or self._kept[0].shape[memory[0].batch_axis] != count):
            self._kept = [m.zeros(count) for m in memory]
        step = min(INFERENCE_ROWS, self.info.cost.rows_per_call)
        parts = []
        for at in range(0, max(count, 1), step):
            part = slice(at, at + step)
            inputs = [
                rows[part],
                *(kept[_along(m, part)] for m, kept in zip(memory, self._kept or [], strict=True)),
            ]
            try:
                answer = self._box.run(
                    inputs, limit_s=self.limits.call_s, keep_going=self.keep_going
                )
            except Interrupted:
                raise Stopped("stopped while the network decided") from None
            if len(answer) != 1 + len(memory):
                raise ValueError(f"the model gave {len(answer)} outputs, not {1 + len(memory)}")
            for m, kept, new in zip(memory, self._kept or [], answer[1:], strict=True):
                if new.shape != kept[_along(m, part)].shape:
                    raise ValueError(f"the model's memory {m.output_name!r} came back reshaped")
                kept[_along(m, part)] = new
            parts.append(checked_answer(answer[0], rows[part], self.info, self.actions))
        whole = parts[0] if len(parts) == 1 else np.concatenate(parts)
        if self.info.output == "turn":
            turns: NDArray[np.float64] = whole.astype(np.float64)
            return turns
        if self.info.output == "logits":
            chosen: NDArray[np.int64] = np.argmax(whole, axis=1).astype(np.int64)
            return chosen
        actions: NDArray[np.int64] = whole
        return actions
