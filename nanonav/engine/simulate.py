"""Run a scenario: training episodes, then one greedy evaluation episode that is recorded.

The engine takes a scenario (with its seed) and returns a result; it reads no clock but
``time.perf_counter`` for the work figures, touches no global RNG, no file and no database.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from nanonav.engine import fields, kernel, metrics, qlearning, state
from nanonav.engine.result import QTable, SimulationResult, Trajectory
from nanonav.engine.state import KernelParams, Learner, Recording, Swarm, World
from nanonav.engine.world import episode_generator, raise_for_layout
from nanonav.scenario import Scenario

# Robot-steps per compiled call between progress reports (about 0.1 s of work).
CHUNK_ROBOT_STEPS = 100_000
# At most this many robot-rows of history are kept for the evaluation episode.
RECORD_BUDGET = 2_000_000


@dataclass(frozen=True)
class Progress:
    """Where a run is: ``episode`` episodes finished of ``episodes`` (training plus the
    evaluation), and ``step`` steps into the current one."""

    episode: int
    episodes: int
    step: int
    max_steps: int

    @property
    def fraction(self) -> float:
        done = self.episode + min(self.step / self.max_steps, 1.0)
        return min(done / self.episodes, 1.0)


ProgressCallback = Callable[[Progress], bool | None]


def _params(scenario: Scenario) -> KernelParams:
    """The kernel's constants for training episodes; evaluation swaps a few with ``_replace``."""
    b = scenario.biomarker
    base = max(scenario.robots.sensing_radius, scenario.robots.speed)
    levels = fields.radial_profile(b, base * np.array(qlearning.LEVEL_DISTANCES))
    return KernelParams(
        model=fields.MODEL_CODES[b.model],
        weight=fields.source_weight(b),
        length=fields.length_scale(b),
        softening=b.softening,
        noise=b.sensor_noise,
        half=scenario.space.size / 2,
        cell_std=scenario.cells.motion_std,
        obstacle_radius=scenario.obstacles.radius,
        obstacle_std=scenario.obstacles.motion_std,
        speed=scenario.robots.speed,
        sensing_radius=scenario.robots.sensing_radius,
        reach_distance=scenario.reach_distance,
        policy=state.POLICY_CODES[scenario.robots.policy],
        action_set=state.ACTION_SET_CODES[scenario.learning.actions],
        shared=scenario.learning.shared_table,
        learn=scenario.robots.policy == "q_learning",
        alpha=scenario.learning.alpha,
        gamma=scenario.learning.gamma,
        epsilon=0.0,
        reward_reach=scenario.rewards.reach,
        reward_collision=scenario.rewards.collision,
        reward_approach=scenario.rewards.approach,
        level_1=float(levels[0]),
        level_2=float(levels[1]),
        level_3=float(levels[2]),
        max_steps=scenario.learning.max_steps,
        record=False,
        record_stride=record_stride(scenario.robots.count, scenario.learning.max_steps),
        emitter_scatter=b.emitter_scatter,
    )


def _learner(scenario: Scenario) -> Learner:
    if scenario.robots.policy != "q_learning":
        shape: tuple[int, int, int] = (1, 1, 1)
    else:
        states, actions = qlearning.labels(scenario.learning.actions)
        tables = 1 if scenario.learning.shared_table else scenario.robots.count
        shape = (tables, len(states), len(actions))
    return Learner(
        q=np.zeros(shape),
        visits=np.zeros(shape, dtype=np.int64),
        directions=np.ascontiguousarray(qlearning.DIRECTIONS),
    )


def record_stride(robots: int, max_steps: int) -> int:
    """Steps between history rows, so that the evaluation's history stays within budget."""
    rows = max(RECORD_BUDGET // robots - 2, 1)
    return max(1, math.ceil(max_steps / rows))


class _Episode:
    """One episode: its arrays, its generator and its step counter. The kernel draws the world
    on the first ``advance``."""

    def __init__(
        self, scenario: Scenario, index: int, params: KernelParams, learner: Learner
    ) -> None:
        self.scenario = scenario
        self.rng = episode_generator(scenario.seed, index)
        self.params = params
        self.learner = learner
        n = scenario.robots.count
        cells = scenario.cells.count
        obstacles = scenario.obstacles.count
        k = fields.source_count(scenario.biomarker, cells)
        self.world = World(
            cells=np.empty((cells, 3)),
            obstacles=np.empty((obstacles, 3)),
            offsets=np.zeros((k if params.model == fields.INVERSE_SQUARE else 0, 3)),
            sx=np.empty(k),
            sy=np.empty(k),
            sz=np.empty(k),
        )
        self.swarm = Swarm(
            pos=np.empty((n, 3)),
            heading=np.empty((n, 3)),
            active=np.ones(n, dtype=np.bool_),
            steps=np.zeros(n, dtype=np.int64),
            prev_conc=np.full(n, -1.0),
            returns=np.zeros(n),
            collisions=np.zeros(n, dtype=np.int64),
            path_length=np.zeros(n),
            pending=np.zeros(n, dtype=np.bool_),
            last_state=np.zeros(n, dtype=np.int64),
            last_action=np.zeros(n, dtype=np.int64),
            last_reward=np.zeros(n),
            start=np.empty((n, 3)),
            sum_conc=np.zeros(n),
            sum_dist=np.zeros(n),
            last_dist=np.zeros(n),
        )
        rows = params.max_steps // params.record_stride + 2 if params.record else 1
        self.recording = Recording(
            pos=np.zeros((rows, n, 3)),
            cells=np.zeros((rows, cells, 3)),
            obstacles=np.zeros((rows, obstacles, 3)),
            conc=np.zeros((rows, n)),
            dist=np.zeros((rows, n)),
            step=np.zeros(rows, dtype=np.int64),
        )
        self.t = 0
        self.counters = np.zeros(2, dtype=np.int64)

    @property
    def over(self) -> bool:
        return self.t >= self.params.max_steps or not self.swarm.active.any()

    def advance(self, n_steps: int) -> None:
        self.t = kernel.run_steps(
            self.params, self.rng, self.world, self.swarm, self.learner, self.recording,
            self.t, n_steps, self.counters,
        )  # fmt: skip
        raise_for_layout(int(self.counters[state.LAYOUT_STATUS]), self.scenario)

    @property
    def robot_steps(self) -> int:
        return int(self.counters[state.ROBOT_STEPS])

    def trajectory(self) -> Trajectory:
        stride = self.params.record_stride
        rows = self.t // stride + 1 + (1 if self.t % stride else 0)
        r = self.recording
        cells = self.scenario.cells.count
        return Trajectory(
            step=r.step[:rows].copy(),
            robots=r.pos[:rows].copy(),
            cells=r.cells[:rows].copy(),
            obstacles=r.obstacles[:rows].copy(),
            concentration=r.conc[:rows].copy(),
            distance=r.dist[:rows].copy(),
            steps=self.swarm.steps.copy(),
            reached=~self.swarm.active,
            emitter_offsets=self.world.offsets.reshape(cells, -1, 3).copy(),
            obstacle_radius=self.params.obstacle_radius,
            stride=stride,
        )


_compiled = False


def _warm_up() -> None:
    """Compile (or load from numba's cache) every kernel once per process, so that ``work``
    measures simulation, not start-up."""
    global _compiled
    if _compiled:
        return
    tiny = Scenario.model_validate(
        {"learning": {"episodes": 0, "max_steps": 2}, "obstacles": {"count": 1}}
    )
    params = _params(tiny)._replace(record=True)
    episode = _Episode(tiny, 0, params, _learner(tiny))
    episode.advance(2)
    fields.field_and_gradient(
        tiny.biomarker, episode.world.cells, np.zeros((1, 0, 3)), np.zeros((1, 3))
    )
    _compiled = True


def simulate(scenario: Scenario, progress: ProgressCallback | None = None) -> SimulationResult:
    """Train for ``learning.episodes`` episodes, then record one greedy evaluation episode.

    ``progress`` is called between chunks of steps and after every episode; returning False
    stops the run, and the result keeps the episodes finished so far (``completed`` False).
    """
    _warm_up()
    learning = scenario.learning
    total = learning.episodes + 1
    chunk = max(1, CHUNK_ROBOT_STEPS // scenario.robots.count)
    learner = _learner(scenario)
    is_q = scenario.robots.policy == "q_learning"
    training = _params(scenario)

    curve: list[dict[str, Any]] = []
    robot_steps = 0
    engine_s = 0.0
    evaluation: _Episode | None = None
    eval_s = 0.0

    def report(done: int, step: int) -> bool:
        if progress is None:
            return True
        return progress(Progress(done, total, step, learning.max_steps)) is not False

    for index in range(total):
        evaluating = index == learning.episodes
        eps = 0.0 if evaluating or not is_q else qlearning.epsilon(learning, index)
        started = time.perf_counter()
        if evaluating:
            params = training._replace(epsilon=0.0, learn=False, record=True)
        else:
            params = training._replace(epsilon=eps)
        episode = _Episode(scenario, index, params, learner)
        episode_s = 0.0
        while not episode.over:
            episode.advance(chunk)
            episode_s += time.perf_counter() - started
            if not episode.over and not report(index, episode.t):
                break
            started = time.perf_counter()
        engine_s += episode_s
        robot_steps += episode.robot_steps
        if not episode.over:
            break
        if evaluating:
            evaluation = episode
            eval_s = episode_s
        else:
            s = episode.swarm
            curve.append(
                {
                    "episode": index,
                    "steps": episode.t,
                    "success_rate": float(np.mean(~s.active)),
                    "mean_return": float(np.mean(s.returns)),
                    "epsilon": eps,
                    "collisions": int(s.collisions.sum()),
                }
            )
        if not report(index + 1, 0):
            break

    work = {"robot_steps": robot_steps, "engine_s": engine_s}
    qtable = None
    if is_q:
        states, actions = qlearning.labels(learning.actions)
        values = learner.q[0] if learning.shared_table else learner.q
        visits = learner.visits[0] if learning.shared_table else learner.visits
        qtable = QTable(states, actions, values.copy(), visits.copy())
    if evaluation is None:
        return SimulationResult(scenario, {}, [], curve, work, None, qtable, completed=False)
    rows = metrics.robot_rows(evaluation.swarm, eval_s, evaluation.t)
    summary = metrics.swarm_summary(rows, evaluation.t, eval_s)
    trajectory = evaluation.trajectory()
    return SimulationResult(scenario, summary, rows, curve, work, trajectory, qtable)
