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

from nanonav.engine import fields, kernel, metrics, qlearning
from nanonav.engine.kernel import KernelParams, Learner, Recording, Swarm, World
from nanonav.engine.result import QTable, SimulationResult, Trajectory
from nanonav.engine.world import Layout, draw_layout, episode_generators
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


def _params(
    scenario: Scenario, *, epsilon: float, learn: bool, record: bool, stride: int
) -> KernelParams:
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
        policy=kernel.POLICY_CODES[scenario.robots.policy],
        action_set=kernel.ACTION_SET_CODES[scenario.learning.actions],
        shared=scenario.learning.shared_table,
        learn=learn,
        alpha=scenario.learning.alpha,
        gamma=scenario.learning.gamma,
        epsilon=epsilon,
        reward_reach=scenario.rewards.reach,
        reward_collision=scenario.rewards.collision,
        reward_approach=scenario.rewards.approach,
        level_1=float(levels[0]),
        level_2=float(levels[1]),
        level_3=float(levels[2]),
        max_steps=scenario.learning.max_steps,
        record=record,
        record_stride=stride,
    )


def _swarm(layout: Layout) -> Swarm:
    n = layout.robots.shape[0]
    return Swarm(
        pos=layout.robots.copy(),
        heading=layout.headings.copy(),
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
        start=layout.robots.copy(),
        sum_conc=np.zeros(n),
        sum_dist=np.zeros(n),
        last_dist=np.zeros(n),
    )


def _world(scenario: Scenario, layout: Layout) -> World:
    k = fields.source_count(scenario.biomarker, layout.cells.shape[0])
    return World(
        cells=layout.cells.copy(),
        obstacles=layout.obstacles.copy(),
        offsets=np.ascontiguousarray(layout.emitter_offsets.reshape(-1, 3)),
        sx=np.empty(k),
        sy=np.empty(k),
        sz=np.empty(k),
    )


def _recording(rows: int, robots: int, cells: int, obstacles: int) -> Recording:
    return Recording(
        pos=np.zeros((rows, robots, 3)),
        cells=np.zeros((rows, cells, 3)),
        obstacles=np.zeros((rows, obstacles, 3)),
        conc=np.zeros((rows, robots)),
        dist=np.zeros((rows, robots)),
        step=np.zeros(rows, dtype=np.int64),
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
    """One episode in progress: its arrays, generator and step counter."""

    def __init__(
        self, scenario: Scenario, index: int, params: KernelParams, learner: Learner
    ) -> None:
        world_rng, self.rng = episode_generators(scenario.seed, index)
        self.layout = draw_layout(scenario, world_rng)
        self.params = params
        self.world = _world(scenario, self.layout)
        self.swarm = _swarm(self.layout)
        self.learner = learner
        rows = scenario.learning.max_steps // params.record_stride + 2 if params.record else 1
        self.recording = _recording(
            rows, scenario.robots.count, scenario.cells.count, scenario.obstacles.count
        )
        self.t = 0
        self.counters = np.zeros(1, dtype=np.int64)
        if params.record:
            fields.place_sources(
                params.model, self.world.cells, self.world.offsets,
                self.world.sx, self.world.sy, self.world.sz,
            )  # fmt: skip
            kernel.observe(params, self.world, self.swarm, self.recording, 0, False)

    @property
    def over(self) -> bool:
        return self.t >= self.params.max_steps or not self.swarm.active.any()

    def advance(self, n_steps: int) -> None:
        self.t = kernel.run_steps(
            self.params, self.rng, self.world, self.swarm, self.learner, self.recording,
            self.t, n_steps, self.counters,
        )  # fmt: skip

    def finish(self) -> None:
        kernel.finish_episode(self.params, self.rng, self.world, self.swarm, self.learner)
        if self.params.record and self.t % self.params.record_stride:
            kernel.observe(self.params, self.world, self.swarm, self.recording, self.t, True)

    def trajectory(self, radius: float) -> Trajectory:
        rows = self.t // self.params.record_stride + 1
        if self.t % self.params.record_stride:
            rows += 1
        r = self.recording
        return Trajectory(
            step=r.step[:rows].copy(),
            robots=r.pos[:rows].copy(),
            cells=r.cells[:rows].copy(),
            obstacles=r.obstacles[:rows].copy(),
            concentration=r.conc[:rows].copy(),
            distance=r.dist[:rows].copy(),
            steps=self.swarm.steps.copy(),
            reached=~self.swarm.active,
            emitter_offsets=self.layout.emitter_offsets.copy(),
            obstacle_radius=radius,
            stride=self.params.record_stride,
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
    learner = _learner(tiny)
    episode = _Episode(tiny, 0, _params(tiny, epsilon=0.0, learn=True, record=True, stride=1),
                       learner)  # fmt: skip
    episode.advance(2)
    episode.finish()
    fields.field_and_gradient(tiny.biomarker, episode.world.cells, np.zeros((1, 0, 3)),
                              np.zeros((1, 3)))  # fmt: skip
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
    stride = record_stride(scenario.robots.count, learning.max_steps)

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
        params = _params(
            scenario, epsilon=eps, learn=is_q and not evaluating, record=evaluating, stride=stride
        )
        episode = _Episode(scenario, index, params, learner)
        stopped = False
        while not episode.over:
            episode.advance(chunk)
            if not episode.over:
                engine_s += time.perf_counter() - started
                stopped = not report(index, episode.t)
                started = time.perf_counter()
                if stopped:
                    break
        if stopped:
            break
        episode.finish()
        elapsed = time.perf_counter() - started
        engine_s += elapsed
        robot_steps += int(episode.counters[0])
        if evaluating:
            evaluation = episode
            eval_s = elapsed
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
    trajectory = evaluation.trajectory(scenario.obstacles.radius)
    return SimulationResult(scenario, summary, rows, curve, work, trajectory, qtable)
