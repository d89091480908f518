"""Many worlds of one scenario, driven from outside: the arrays, the generators and the one
compiled call (``engine.stepping.step_worlds``) that every environment (``nanonav.env``) and
every policy run from outside (``nanonav.rl``) steps them with. What the observation means,
its units and its bounds are in ``engine.observations``, written once for the environments'
spaces, the policies sent as ONNX models and the README alike.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from numba.typed import List
from numpy.typing import NDArray

from nanonav.engine import phases, qlearning, stepping
from nanonav.engine.generators import handle
from nanonav.engine.observations import action_labels
from nanonav.engine.simulation import (
    DEFAULT_RECORD_BYTES,
    empty_recording,
    episode_arrays,
    kernel_params,
)
from nanonav.engine.state import SCHEDULE_CODES, KernelParams, Recording
from nanonav.engine.world import DYNAMICS_STREAM, EVALUATION_STREAM, raise_for_layout, stream
from nanonav.scenario import (
    STEERINGS,
    Scenario,
    Schedule,
    Steering,
)

# No history is recorded: the cap only keeps kernel_params from refusing a large swarm.
_NO_HISTORY_CAP = 2**62


def _empty_recording(robots: int, cells: int) -> Recording:
    nothing = np.zeros((0, robots))
    return Recording(
        pos=np.zeros((0, robots, 3)),
        cells=np.zeros((0, cells, 3)),
        obstacles=np.zeros((0, 0, 3)),
        conc=nothing,
        dist=nothing,
        step=np.zeros(0, dtype=np.int64),
        offsets=np.zeros((0, 3)),
        heading=np.zeros((0, robots, 3)),
        sensed=nothing,
        load=np.zeros((0, cells), dtype=np.int64),
        signal=nothing,
    )


def _stacked(one: Any, count: int) -> Any:
    """``one`` (a NamedTuple of arrays, scalars and such tuples) with every array repeated
    along a new leading axis of ``count`` worlds; scalars are shared."""
    if isinstance(one, np.ndarray):
        return np.ascontiguousarray(np.repeat(one[np.newaxis], count, axis=0))
    if isinstance(one, tuple):
        return type(one)(*(_stacked(part, count) for part in one))
    return one


class Worlds:
    """``count`` independent worlds of ``scenario``, each with its robots and its two
    generators (the worlds' and the dynamics'), stepped together in one compiled call under
    ``schedule`` (an environment's API decides it, whatever the scenario's: ``stepping`` says
    what a move is under each).

    World k seeded with s draws, episode after episode, the worlds a job of seed s evaluates
    in (``simulate``'s evaluation stream) and runs on the dynamics stream of seed s, so a policy
    evaluated here with seed s meets what the service would evaluate it in: train on other seeds.
    """

    def __init__(
        self,
        scenario: Scenario,
        count: int,
        schedule: Schedule,
        *,
        measure: int = 0,
        record_bytes: int = DEFAULT_RECORD_BYTES,
        steering: Steering = "discrete",
    ) -> None:
        """``measure``: 0 for an environment's worlds; ``phases.MEASURED`` to tally them as
        ``simulate``'s evaluation does, ``phases.RECORDED`` to record their history too, in at
        most ``record_bytes`` a world (``simulate``'s rows). ``steering``: ``continuous``
        (active_brownian only) takes a turn (side, up) per robot for its action."""
        if count < 1:
            raise ValueError("count must be at least 1")
        if steering not in STEERINGS:
            raise ValueError(f"steering {steering!r} is not one of {', '.join(STEERINGS)}")
        self.continuous = steering == "continuous"
        if self.continuous and scenario.physics.model != "active_brownian":
            raise ValueError("continuous steering needs physics.model 'active_brownian'")
        self.steering = steering
        self.scenario = scenario
        self.count = count
        self.robots = scenario.robots.count
        self.schedule = schedule
        # the agent outside decides by action number: it holds each action for the scenario's
        # decision interval, whatever policy the scenario names
        recorded = measure == phases.RECORDED
        self.params = kernel_params(
            scenario, record_bytes if recorded else _NO_HISTORY_CAP
        )._replace(
            schedule=SCHEDULE_CODES[schedule], hold=scenario.decision_steps,
            turning=self.continuous,
        )  # fmt: skip
        self.actions = len(action_labels(scenario, steering))
        self.directions = np.ascontiguousarray(qlearning.DIRECTIONS)
        arrays = episode_arrays(scenario)
        n = self.robots
        one = phases.Sim(
            arrays.world, arrays.swarm, arrays.social, arrays.treatment, arrays.near,
            arrays.radio, arrays.everyone, arrays.found, arrays.signals.conc,
            arrays.signals.scratch,
            empty_recording(scenario, self.params.record_stride)
            if recorded
            else _empty_recording(n, scenario.cells.count),
            phases.percept(n),
        )  # fmt: skip
        self.batch: phases.Sim = _stacked(one, count)
        # each world's generators as the compiled step takes them (``generators``), and the
        # generators themselves, kept alive here while their handles are used
        self._world_rngs = [stream(scenario.seed + k, EVALUATION_STREAM) for k in range(count)]
        self._rngs = [stream(scenario.seed + k, DYNAMICS_STREAM) for k in range(count)]
        self._world_handles = np.stack([handle(g) for g in self._world_rngs])
        self._handles = np.stack([handle(g) for g in self._rngs])
        # what every call hands the compiled step, in one list (``due``: its scratch)
        due = np.zeros(count, dtype=np.int64)
        self._held: List[
            tuple[
                KernelParams,
                phases.Sim,
                NDArray[np.uint64],
                NDArray[np.uint64],
                NDArray[np.int64],
            ]
        ] = stepping.held(self.params, self.batch, self._world_handles, self._handles, due)
        pc = self.batch.pc
        self.obs = pc.obs  # (worlds, robots, features)
        self.state = pc.state
        self.reward = pc.reward
        self.active = self.batch.s.active
        pc.clock[:, phases.CLOCK_OVER] = 1
        pc.clock[:, phases.CLOCK_MEASURE] = measure
        self._no_actions = np.zeros((count, self.robots), dtype=np.int64)
        self._turns = np.zeros((count, self.robots, 2))

    def seed(self, seeds: Sequence[int]) -> None:
        """Restart world k's generators from ``seeds[k]``."""
        if len(seeds) != self.count:
            raise ValueError(f"{len(seeds)} seeds for {self.count} worlds")
        for k, seed in enumerate(seeds):
            self.use_generators(
                k, stream(int(seed), EVALUATION_STREAM), stream(int(seed), DYNAMICS_STREAM)
            )

    def use_generators(
        self, k: int, world_rng: np.random.Generator, rng: np.random.Generator
    ) -> None:
        """World k draws its fresh worlds from ``world_rng`` and its dynamics from ``rng``
        from its next step on (one generator may serve many worlds, drawn in turn)."""
        self._world_rngs[k] = world_rng
        self._rngs[k] = rng
        self._world_handles[k] = handle(world_rng)
        self._handles[k] = handle(rng)

    def step(
        self, actions: NDArray[Any] | None, fresh: NDArray[np.bool_], *, checked: bool = False
    ) -> None:
        """Step every world on ``actions`` (worlds x robots, or worlds x robots x 2 turns
        steering continuously; an inactive robot's are unused), or draw a fresh one where
        ``fresh``; the outputs are in ``obs``, ``state``, ``reward``, ``active`` and ``over``.
        An action that is not an integer of the action set, or a turn that is not finite,
        raises ValueError, unless the caller ``checked`` them already (an action the engine
        indexes with unchecked would read memory that is not its own). A turn's parts are
        clipped to -1 .. 1."""
        if actions is None:
            self._call(self._no_actions, fresh, advance=True)
            return
        if not checked:
            self.check(actions, self.action_shape)
        if self.continuous:
            self._turns[:] = actions
            self._call(self._no_actions, fresh, advance=True)
            return
        self._call(actions.astype(np.int64, copy=False), fresh, advance=True)

    def redraw(self, fresh: NDArray[np.bool_]) -> None:
        """Draw a fresh world where ``fresh`` and leave every other world as it is, outputs
        included (Stable-Baselines3's same-step reset)."""
        self._call(self._no_actions, fresh, advance=False)

    def _call(self, actions: NDArray[np.int64], fresh: NDArray[np.bool_], advance: bool) -> None:
        status = stepping.step_worlds(
            self._held, actions, self._turns, fresh, self.directions, advance,
        )  # fmt: skip
        raise_for_layout(status, self.scenario)

    @property
    def action_shape(self) -> tuple[int, ...]:
        """The shape of ``step``'s actions: worlds x robots, and x 2 steering continuously."""
        if self.continuous:
            return (self.count, self.robots, 2)
        return (self.count, self.robots)

    def blank_actions(self) -> NDArray[Any]:
        """Zeros shaped and typed as ``step``'s actions (integers, or turns steering
        continuously), for a caller to fill in."""
        return np.zeros(self.action_shape, dtype=np.float64 if self.continuous else np.int64)

    def in_action_set(self, actions: NDArray[Any]) -> bool:
        """Whether every one of ``actions`` is an integer of the action set (steering
        continuously: a finite number)."""
        if self.continuous:
            return actions.dtype.kind in "iuf" and bool(np.isfinite(actions).all())
        return actions.dtype.kind in "iu" and (
            not actions.size or (actions.min() >= 0 and actions.max() < self.actions)
        )

    def check(self, actions: NDArray[Any], shape: tuple[int, ...]) -> None:
        """Refuse ``actions`` not shaped ``shape``, or not all integers of the action set
        (steering continuously: not all finite numbers)."""
        if actions.shape != shape:
            raise ValueError(f"actions of shape {actions.shape}, not {shape}")
        if self.continuous:
            if not self.in_action_set(actions):
                raise ValueError(f"turns of {actions.dtype} must be finite numbers")
            return
        if actions.dtype.kind not in "iu":
            raise ValueError(f"actions of {actions.dtype}, not integers")
        if not self.in_action_set(actions):
            bad = actions[(actions < 0) | (actions >= self.actions)][0]
            raise ValueError(f"action {bad} is not in the action set 0..{self.actions - 1}")

    @property
    def over(self) -> NDArray[np.bool_]:
        """Whether each world's episode is over."""
        over: NDArray[np.bool_] = self.batch.pc.clock[:, phases.CLOCK_OVER] != 0
        return over

    def turn(self, k: int) -> int:
        """The robot whose turn it is in world ``k`` (the sequential schedule; -1 once over)."""
        return int(self.batch.pc.clock[k, phases.CLOCK_NEXT])

    def steps(self, k: int) -> int:
        """The step world ``k`` is at."""
        return int(self.batch.pc.clock[k, phases.CLOCK_STEP])
