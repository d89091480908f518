"""Run a scenario: training episodes, then one greedy evaluation episode that is recorded.

The engine takes a scenario (with its seed) and returns a result; it reads no clock but
``time.perf_counter`` for the work figures, touches no global RNG, no file and no database.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import NDArray

from nanonav.engine import (
    communication,
    contacts,
    fields,
    kernel,
    metrics,
    phases,
    qlearning,
    sensing,
    signals,
    state,
)  # fmt: skip
from nanonav.engine.compiled import in_cache
from nanonav.engine.dynamics import brownian
from nanonav.engine.dynamics.brownian import heading_kick_scale
from nanonav.engine.result import QTable, SimulationResult, Trajectory
from nanonav.engine.state import (
    KernelParams,
    Learner,
    Recording,
    Social,
    Swarm,
    Treatment,
    World,
)
from nanonav.engine.world import (
    DYNAMICS_STREAM,
    EVALUATION_STREAM,
    WORLD_STREAM,
    raise_for_layout,
    stream,
)
from nanonav.scenario import MOLECULES_PER_UM3_PER_NM, Biomarker, Scenario, ScenarioError

# Robot-steps per compiled call between progress reports (about 0.1 s of work).
CHUNK_ROBOT_STEPS = 100_000
# Bytes the evaluation's history may take (and allocate): 16 MiB.
DEFAULT_RECORD_BYTES = 16 * 2**20
FLOAT_BYTES = 8  # float64 and int64 alike


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


def kernel_params(scenario: Scenario, record_bytes: int = DEFAULT_RECORD_BYTES) -> KernelParams:
    """The kernel's constants, flattened from the scenario."""
    b = fields.biomarker_of(scenario)
    base = max(scenario.robots.sensing_radius, scenario.robots.speed)
    levels = fields.radial_profile(b, base * np.array(qlearning.LEVEL_DISTANCES))
    params = KernelParams(
        model=fields.MODEL_CODES[b.model],
        weight=fields.source_weight(b),
        length=fields.length_scale(b),
        softening=b.softening,
        noise=b.sensor_noise,
        half=scenario.space.size / 2,
        cell_std=scenario.cells.motion_std,
        cell_margin=scenario.obstacles.radius,
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
        gamma=scenario.discount,
        reward_reach=scenario.rewards.reach,
        reward_collision=scenario.step_rewards[1],
        reward_approach=scenario.rewards.approach,
        level_1=float(levels[0]),
        level_2=float(levels[1]),
        level_3=float(levels[2]),
        max_steps=scenario.learning.max_steps,
        record_stride=record_stride(scenario, record_bytes),
        emitter_scatter=b.emitter_scatter,
        noise_floor=b.noise_floor,
        # a gradient component is the difference of two readings sensor_baseline apart
        # (c1 + e1 - c2 - e2) / baseline, e1 and e2 independent: sd sqrt(2) floor / baseline
        gradient_noise=math.sqrt(2.0) * b.noise_floor / scenario.robots.sensor_baseline,
        detection_threshold=b.detection_threshold,
        cell_sensing_radius=scenario.robots.cell_sensing_radius,
        reward_step=scenario.step_rewards[0],
        alpha_schedule=state.ALPHA_SCHEDULE_CODES[scenario.learning.alpha_schedule],
        alpha_exponent=scenario.alpha_exponent,
        cell_extent=scenario.cells.start_extent,
        walls=scenario.space.walls,
        robot_corner=scenario.robots.start == "corner",
        schedule=state.SCHEDULE_CODES[scenario.robots.schedule],
        # the learner decides every decision_steps; a fixed rule, every step
        hold=scenario.decision_steps if scenario.robots.policy == "q_learning" else 1,
    )
    if scenario.physics.model == "active_brownian":
        params = _brownian_params(scenario, params, b)
    return _swarm_params(scenario, params)


def _swarm_params(scenario: Scenario, params: KernelParams) -> KernelParams:
    """Treatable cells, exclusion and signalling, in the units of the scenario's physics: the
    signal's rates per engine step, its grid solver's step the largest stable one (a whole
    number of engine steps, or a whole number of solver steps per engine step)."""
    comm = scenario.communication
    diffusion, decay, release = scenario.signal_rates
    # sensor 'each_step': a reading of c nM of the signal counts pi D a c dt molecules (as the
    # biomarker's); 'counted': the signal's molecules counted as the biomarker's are, by the
    # same receptor patches, with the signal's diffusion coefficient
    signal_counting = signal_patch_rate = signal_patch_gradient_rate = 0.0
    ph = scenario.physics
    if ph.model == "active_brownian":
        radius = ph.robot_radius_um
        signal_counting = (
            math.pi * comm.diffusion_um2_s * radius * ph.step_s * MOLECULES_PER_UM3_PER_NM
        )
    if ph.model == "active_brownian" and ph.sensor == "counted":
        per_nm, per_gradient = brownian.patch_rates(
            comm.diffusion_um2_s, radius,
            *brownian.absorbed_fractions(ph.receptors, ph.receptor_radius_nm * 1e-3, radius),
        )  # fmt: skip
        signal_patch_rate = per_nm * ph.step_s
        signal_patch_gradient_rate = per_gradient * ph.step_s
    grid = signal_grid(scenario)
    every, substeps = scenario.signal_solver_steps
    return params._replace(
        capacity=scenario.cells.capacity or 0,
        treated_secretion=scenario.cells.treated_secretion,
        exclusion=scenario.robots.exclusion,
        contact=2.0 * scenario.robot_radius,
        signal=state.COMMUNICATION_CODES[comm.model],
        signal_states=max(1, len(qlearning.signal_states(comm.model))),
        signal_every=every,
        signal_substeps=substeps,
        signal_diffusion=diffusion,
        signal_decay=decay,
        signal_release=release,
        # the biomarker's noise rules hold for the signal too, its detection threshold with them
        signal_threshold=max(comm.threshold, params.detection_threshold),
        signal_counting=signal_counting,
        signal_patch_rate=signal_patch_rate,
        signal_patch_gradient_rate=signal_patch_gradient_rate,
        signal_origin=grid.origin,
        signal_spacing=grid.spacing,
        signal_dims=grid.dims,
        broadcast_range=comm.range,
    )


def signal_grid(scenario: Scenario) -> signals.SignalGrid:
    """The grid the scenario's chemical signal is solved on (a token one without it)."""
    model = scenario.communication.model
    half = scenario.space.size / 2
    if model in ("attractant", "attractant_repellent"):
        species = 2 if model == "attractant_repellent" else 1
        nodes = scenario.communication.nodes_per_axis
        # the solver's reflecting faces lie half a spacing beyond its outer nodes: on the walls
        return signals.grid_for(half * (nodes - 1) / nodes, nodes, species)
    return signals.grid_for(half, 2, 1)


def _following(every_s: float, memory_s: float) -> float:
    """The weight a new value taken every ``every_s`` has in an exponential average over
    ``memory_s`` (at most 1; a memory of 0 keeps the last value alone)."""
    return min(1.0, every_s / memory_s) if memory_s > 0 else 1.0


def _brownian_params(scenario: Scenario, params: KernelParams, b: Biomarker) -> KernelParams:
    """The active Brownian physics' constants per step of dt_s (um, s, nM). A robot reaches a
    cell when their surfaces touch; its centre stays an obstacle's radius plus its own from the
    obstacle's centre; the Q-learning levels are cut at the lone cell's field at multiples of
    the cell's radius."""
    ph = scenario.physics
    dt = ph.step_s
    d_t = ph.diffusion_um2_s or 0.0
    d_r = ph.rotational_diffusion_s or 0.0
    radius = ph.robot_radius_um
    # sensor 'each_step': a reading over dt by a sensor of radius a counts pi D_m a c dt
    # molecules (Bialek & Setayeshgar's single receptor of the body's size)
    counting = math.pi * ph.molecule_diffusion_um2_s * radius * dt * MOLECULES_PER_UM3_PER_NM
    # sensor 'counted': a count over whole steps of what each receptor patch of an absorbing
    # body takes in (``brownian.patch_rates``)
    window = max(1, round((ph.integration_time_s or dt) / dt))
    per_nm, per_gradient = brownian.patch_rates(
        ph.molecule_diffusion_um2_s, radius,
        *brownian.absorbed_fractions(ph.receptors, ph.receptor_radius_nm * 1e-3, radius),
    )  # fmt: skip
    levels = fields.radial_profile(b, ph.cell_radius_um * np.array(qlearning.STEERING_LEVEL_RADII))
    return params._replace(
        physics=state.ACTIVE_BROWNIAN,
        speed=ph.swim_speed_um_s * dt,
        # cells diffuse, their surface kept off the obstacles'
        cell_std=math.sqrt(2.0 * ph.cell_diffusion_um2_s * dt),
        cell_margin=scenario.obstacles.radius + ph.cell_radius_um,
        obstacle_std=0.0,
        noise=0.0,
        noise_floor=0.0,
        gradient_noise=0.0,
        detection_threshold=0.0,
        reach_distance=radius + ph.cell_radius_um,
        obstacle_radius=scenario.obstacles.radius + radius,
        level_1=float(levels[0]),
        level_2=float(levels[1]),
        level_3=float(levels[2]),
        jiggle=math.sqrt(2.0 * d_t * dt),
        heading_sigma=heading_kick_scale(d_r, dt),
        turn=ph.max_turn_rate_rad_s * dt,
        robot_radius=radius,
        counting=counting,
        tumble=-math.expm1(-ph.tumble_rate_s * dt),
        tumble_rising=-math.expm1(-ph.tumble_rate_rising_s * dt),
        memory_weight=_following(dt, ph.memory_s),
        recent_weight=_following(dt, ph.short_memory_s),
        counted=ph.sensor == "counted",
        window=window,
        patch_rate=per_nm * dt,
        patch_gradient_rate=per_gradient * dt,
        gradient_weight=_following(window * dt, ph.gradient_memory_s),
    )  # fmt: skip


def _learner(scenario: Scenario, policy: NDArray[np.float64] | None = None) -> Learner:
    if scenario.robots.policy != "q_learning":
        shape: tuple[int, int, int] = (1, 1, 1)
    else:
        states, actions = qlearning.labels(scenario.learning.actions, scenario.communication.model)
        tables = 1 if scenario.learning.shared_table else scenario.robots.count
        shape = (tables, len(states), len(actions))
    q = np.zeros(shape)
    if policy is not None:
        q[:] = _starting_table(scenario, policy, shape)
    return Learner(
        q=q,
        visits=np.zeros(shape, dtype=np.int64),
        directions=np.ascontiguousarray(qlearning.DIRECTIONS),
    )


def _starting_table(
    scenario: Scenario, policy: NDArray[np.float64], shape: tuple[int, int, int]
) -> NDArray[np.float64]:
    """``policy`` as the learner's starting table: one shared table (states x actions), copied
    to every robot that learns its own, or one table per robot."""
    if scenario.robots.policy != "q_learning":
        raise ScenarioError("robots.policy", "only q_learning starts from a learned table")
    table = np.asarray(policy, dtype=np.float64)
    if table.ndim == 2:
        table = table[np.newaxis]
    fits = table.ndim == 3 and table.shape[1:] == shape[1:] and table.shape[0] in (1, shape[0])
    if not fits or not np.isfinite(table).all():
        raise ScenarioError(
            "policy_from",
            f"the table's shape {tuple(policy.shape)} does not fit {scenario.learning.actions} "
            f"Q-learning with {shape[0]} table(s) of {shape[1]} states x {shape[2]} actions",
        )
    return table


def obstacles_move(scenario: Scenario) -> bool:
    """Whether obstacle centres change during an episode, and so are recorded on every row."""
    return scenario.obstacles.motion_std > 0.0


def history_row_bytes(scenario: Scenario) -> int:
    """Bytes of one history row: per robot a position (3 floats), the concentration and the
    distance (1 each), and in the active Brownian physics its heading (3) and sensed reading
    (1), with a communication model the signal it read (1); per cell a position and its load;
    per obstacle a centre if obstacles move; the step."""
    floats = 5 * scenario.robots.count + 4 * scenario.cells.count + 1
    if scenario.physics.model == "active_brownian":
        floats += 4 * scenario.robots.count  # the heading and the sensed reading
    if scenario.communication.model != "none":
        floats += scenario.robots.count
    if obstacles_move(scenario):
        floats += 3 * scenario.obstacles.count
    return FLOAT_BYTES * floats


def fixed_history_bytes(scenario: Scenario) -> int:
    """Bytes the history keeps once, whatever its length: the recorded world's emitter offsets,
    and the one row of obstacle centres when obstacles do not move."""
    offsets = 3 * scenario.cells.count * scenario.biomarker.emitters_per_cell
    still = 0 if obstacles_move(scenario) else 3 * scenario.obstacles.count
    return FLOAT_BYTES * (offsets + still)


def history_rows(max_steps: int, stride: int) -> int:
    """Most rows an episode of at most ``max_steps`` records: steps 0, stride, 2 stride, ...
    and the last step."""
    return -(-max_steps // stride) + 1


def record_stride(scenario: Scenario, record_bytes: int) -> int:
    """The smallest stride between history rows whose rows all fit in ``record_bytes``.

    Strides only thin what is recorded; the dynamics are the same for every stride. When not even
    the start and the end rows fit, the scenario is refused rather than the cap broken."""
    row = history_row_bytes(scenario)
    rows = (record_bytes - fixed_history_bytes(scenario)) // row
    if rows < 2:
        n, c, o = scenario.robots.count, scenario.cells.count, scenario.obstacles.count
        share = {
            "robots.count": 5 * n,
            "cells.count": 4 * c,
            "obstacles.count": 3 * o * (2 if obstacles_move(scenario) else 1),
        }
        raise ScenarioError(
            max(share, key=share.__getitem__),
            f"one recorded step of {n} robots, {c} cells and {o} obstacles takes {row} bytes; "
            f"the history cap of {record_bytes} bytes cannot hold the episode's start and end",
        )
    # T steps at stride s keep ceil(T / s) + 1 rows: at most `rows` once s >= ceil(T / (rows - 1))
    return -(-scenario.learning.max_steps // (rows - 1))


def swarm_metrics(scenario: Scenario) -> bool:
    """Whether a run reports the swarm's numbers (``metrics.SWARM``): when robots take up
    space, cells can be treated, or robots signal."""
    return (
        scenario.robots.exclusion
        or scenario.cells.capacity is not None
        or scenario.communication.model != "none"
    )


class EpisodeArrays(NamedTuple):
    """The arrays one world's episodes run on, reused from episode to episode."""

    world: World
    swarm: Swarm
    social: Social
    treatment: Treatment
    near: contacts.CellList  # robots that take up space: their neighbours
    radio: contacts.CellList  # broadcast: who hears a sender
    everyone: NDArray[np.bool_]
    found: NDArray[np.int64]  # scratch for a neighbour search's answers
    signals: signals.SignalGrid


def episode_arrays(scenario: Scenario) -> EpisodeArrays:
    """Empty arrays for one world of ``scenario`` (``world.draw_world`` fills them)."""
    n = scenario.robots.count
    cells = scenario.cells.count
    obstacles = scenario.obstacles.count
    k = fields.source_count(scenario.biomarker, cells)
    world = World(
        cells=np.empty((cells, 3)),
        obstacles=np.empty((obstacles, 3)),
        # drawn for every field model, so that all of them see the same worlds
        offsets=np.zeros((cells * scenario.biomarker.emitters_per_cell, 3)),
        sx=np.empty(k),
        sy=np.empty(k),
        sz=np.empty(k),
    )
    treatment = Treatment(
        load=np.zeros(cells, dtype=np.int64),
        treated_at=np.full(cells, -1, dtype=np.int64),
        tx=np.empty(k),
        ty=np.empty(k),
        tz=np.empty(k),
        treated_sources=np.zeros(1, dtype=np.int64),
    )
    swarm = Swarm(
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
        reading=np.zeros(n),
        reading_grad=np.zeros((n, 3)),
        swept=np.zeros(n, dtype=np.bool_),
        blocked=np.zeros(n, dtype=np.bool_),
        sensed=np.zeros(n),
        sensed_grad=np.zeros((n, 3)),
        recent=np.zeros(n),
        window_flux=np.zeros((n, sensing.RECEPTOR_PATCHES + 1)),
    )
    social = Social(
        bound_to=np.full(n, -1, dtype=np.int64),
        bumps=np.zeros(n, dtype=np.int64),
        signal=np.zeros(n),
        prev_signal=np.zeros(n),
        signal_grad=np.zeros((n, 3)),
        signal_flux=np.zeros((n, communication.SIGNAL_STEPS + 1)),
        message=np.zeros((n, 3)),
        has_message=np.zeros(n, dtype=np.bool_),
    )
    half = scenario.space.size / 2
    comm = scenario.communication.model
    near = contacts.grid_for(
        half, 2.0 * scenario.robot_radius if scenario.robots.exclusion else 2 * half, 0.0,
        n if scenario.robots.exclusion else 1,
    )  # fmt: skip
    radio = contacts.grid_for(
        half, scenario.communication.range if comm == "broadcast" else 2 * half, 0.0,
        n if comm == "broadcast" else 1,
    )  # fmt: skip
    return EpisodeArrays(
        world, swarm, social, treatment, near, radio, np.ones(n, dtype=np.bool_),
        np.empty(n, dtype=np.int64), signal_grid(scenario),
    )  # fmt: skip


def empty_recording(scenario: Scenario, stride: int) -> Recording:
    """The arrays of an evaluation world's history, a row every ``stride`` steps."""
    n = scenario.robots.count
    cells = scenario.cells.count
    obstacles = scenario.obstacles.count
    rows = history_rows(scenario.learning.max_steps, stride)
    brownian = scenario.physics.model == "active_brownian"
    signalled = scenario.communication.model != "none"
    return Recording(
        pos=np.zeros((rows, n, 3)),
        cells=np.zeros((rows, cells, 3)),
        obstacles=np.zeros((rows if obstacles_move(scenario) else 1, obstacles, 3)),
        conc=np.zeros((rows, n)),
        dist=np.zeros((rows, n)),
        step=np.zeros(rows, dtype=np.int64),
        offsets=np.zeros((cells * scenario.biomarker.emitters_per_cell, 3)),
        heading=np.zeros((rows if brownian else 0, n, 3)),
        sensed=np.zeros((rows if brownian else 0, n)),
        load=np.zeros((rows, cells), dtype=np.int64),
        signal=np.zeros((rows if signalled else 0, n)),
    )


class Run:
    """The arrays of one run, allocated once and reused by every episode, and the two
    generators: one draws the worlds (so every policy faces the same ones), one the dynamics."""

    def __init__(
        self,
        scenario: Scenario,
        params: KernelParams,
        policy: NDArray[np.float64] | None = None,
    ) -> None:
        self.scenario = scenario
        self.params = params
        self.learner = _learner(scenario, policy)
        learning = scenario.learning
        self.epsilons = np.array(
            [qlearning.epsilon(learning, e) for e in range(learning.episodes)]
            if params.learn
            else np.zeros(learning.episodes)
        )
        self.world_rng = stream(scenario.seed, WORLD_STREAM)
        self.evaluation_rng = stream(scenario.seed, EVALUATION_STREAM)
        self.rng = stream(scenario.seed, DYNAMICS_STREAM)
        n = scenario.robots.count
        cells = scenario.cells.count
        arrays = episode_arrays(scenario)
        self.world = arrays.world
        self.treatment = arrays.treatment
        self.swarm = arrays.swarm
        self.social = arrays.social
        self.near = arrays.near
        self.radio = arrays.radio
        self.everyone = arrays.everyone
        self.found = arrays.found
        self.signals = arrays.signals
        self.recording = empty_recording(scenario, params.record_stride)
        self.sim = phases.Sim(
            self.world, self.swarm, self.social, self.treatment, self.near, self.radio,
            self.everyone, self.found, self.signals.conc, self.signals.scratch, self.recording,
            phases.percept(n),
        )  # fmt: skip
        self.counters = np.zeros(state.COUNTERS, dtype=np.int64)
        self.curve = np.zeros((scenario.episodes, state.CURVE_COLUMNS))
        self.evaluation = np.zeros((scenario.evaluation.worlds, n, state.EV_COLUMNS))
        self.cell_tallies = np.zeros(
            (scenario.evaluation.worlds, cells, state.CELL_COLUMNS), dtype=np.int64
        )

    @property
    def episode(self) -> int:
        return int(self.counters[state.EPISODE])

    @property
    def step(self) -> int:
        return int(self.counters[state.STEP])

    @property
    def robot_steps(self) -> int:
        return int(self.counters[state.ROBOT_STEPS])

    def advance(self, budget: int) -> None:
        """Run about ``budget`` robot-steps, stopping early at the end of training or of the
        evaluation."""
        kernel.run(
            self.params, self.epsilons, self.world_rng, self.evaluation_rng, self.rng, self.sim,
            self.learner, self.counters, self.curve, self.evaluation, budget, self.cell_tallies,
        )  # fmt: skip
        raise_for_layout(int(self.counters[state.LAYOUT_STATUS]), self.scenario)

    def learning_curve(self, episodes: int) -> list[dict[str, Any]]:
        robots = self.scenario.robots.count
        return [
            {
                "episode": e,
                "steps": int(row[state.CURVE_STEPS]),
                "success_rate": float(row[state.CURVE_REACHED] / robots),
                "mean_return": float(row[state.CURVE_RETURN] / robots),
                "epsilon": float(self.epsilons[e]),
                "collisions": int(row[state.CURVE_COLLISIONS]),
            }
            for e, row in enumerate(self.curve[:episodes])
        ]

    def evaluated(self, duration_s: float) -> tuple[list[dict[str, Any]], list[dict[str, Any]]]:
        """Every evaluation world's summary, and the first world's per-robot rows."""
        curve = self.curve[self.scenario.learning.episodes :]
        return evaluated_worlds(
            self.scenario, self.evaluation, self.cell_tallies,
            curve[:, state.CURVE_STEPS].astype(np.int64), curve[:, state.CURVE_ROBOT_STEPS],
            duration_s,
        )  # fmt: skip

    def trajectory(self) -> Trajectory:
        """The first evaluation world's history (valid once it has ended)."""
        length = int(self.curve[self.scenario.learning.episodes, state.CURVE_STEPS])
        return recorded_trajectory(
            self.scenario, self.recording, self.evaluation[0], length, self.params.record_stride
        )


def evaluated_worlds(
    scenario: Scenario,
    tallies: NDArray[np.float64],
    cell_tallies: NDArray[np.int64],
    steps: NDArray[np.int64],
    robot_steps: NDArray[np.float64],
    duration_s: float,
) -> tuple[list[dict[str, Any]], list[dict[str, Any]]]:
    """Every evaluation world's summary from its robots' ``tallies`` (worlds x robots x
    ``state.EV_COLUMNS``), its cells' and its length in ``steps``, and the first world's
    per-robot rows; the wall time is shared out over the worlds by their ``robot_steps``."""
    max_steps = scenario.learning.max_steps
    shares = robot_steps / max(float(robot_steps.sum()), 1.0)
    worlds = [
        metrics.world_summary(world, max_steps, int(length), duration_s * float(share))
        for world, length, share in zip(tallies, steps, shares, strict=True)
    ]
    if swarm_metrics(scenario):
        for world, robots, cells in zip(worlds, tallies, cell_tallies, strict=True):
            world.update(metrics.swarm_summary(robots, cells, scenario.cells.capacity, max_steps))
    rows = metrics.robot_rows(tallies[0], max_steps, duration_s * float(shares[0]), int(steps[0]))
    return worlds, rows


def recorded_trajectory(
    scenario: Scenario,
    recording: Recording,
    tallies: NDArray[np.float64],
    length: int,
    stride: int,
) -> Trajectory:
    """The history of a recorded world whose episode ended after ``length`` steps, with its
    robots' ``tallies`` (robots x ``state.EV_COLUMNS``)."""
    rows = history_rows(length, stride)
    r = recording
    return Trajectory(
        step=r.step[:rows].copy(),
        robots=r.pos[:rows].copy(),
        cells=r.cells[:rows].copy(),
        obstacles=r.obstacles[:rows].copy(),
        concentration=r.conc[:rows].copy(),
        distance=r.dist[:rows].copy(),
        robot_steps=tallies[:, state.EV_STEPS].astype(np.int64),
        reached=tallies[:, state.EV_REACHED] > 0.0,
        emitter_offsets=r.offsets.reshape(scenario.cells.count, -1, 3).copy(),
        obstacle_radius=scenario.obstacles.radius,
        stride=stride,
        headings=r.heading[:rows].copy() if r.heading.shape[0] else None,
        sensed=r.sensed[:rows].copy() if r.sensed.shape[0] else None,
        cell_loads=r.load[:rows].copy(),
        delivered_to=tallies[:, state.EV_CELL].astype(np.int64),
        signals=r.signal[:rows].copy() if r.signal.shape[0] else None,
    )


_compiled = False


def _warm_up() -> None:
    """Compile (or load from numba's cache) every kernel once per process, so that ``work``
    measures simulation, not start-up."""
    global _compiled
    if _compiled:
        return
    tiny = Scenario.model_validate(
        {"learning": {"episodes": 1, "max_steps": 2}, "obstacles": {"count": 1},
         "evaluation": {"worlds": 1}}
    )  # fmt: skip
    run = Run(tiny, kernel_params(tiny))
    while run.episode < tiny.episodes:
        run.advance(CHUNK_ROBOT_STEPS)
    fields.field_and_gradient(
        tiny.biomarker, run.world.cells, np.zeros((1, 0, 3)), np.zeros((1, 3))
    )
    _compiled = True


def compiled_here() -> bool:
    """Whether this machine holds ``simulate``'s machine code (else its first call compiles
    the engine: about a minute on two cores)."""
    return in_cache(kernel.run)


def simulate(
    scenario: Scenario,
    progress: ProgressCallback | None = None,
    *,
    record_bytes: int = DEFAULT_RECORD_BYTES,
    policy: NDArray[np.float64] | None = None,
) -> SimulationResult:
    """Train for ``learning.episodes`` episodes, then record one greedy evaluation episode.

    ``policy`` is a Q-table to start from instead of zeros (a learned one, to evaluate it in
    another world): ``(states, actions)``, or ``(robots, states, actions)`` when every robot
    learns its own; a table that does not fit the scenario raises ``ScenarioError``.

    ``progress`` is called between chunks of about 0.1 s of work and at the end of training;
    returning False stops the run, and the result keeps the episodes finished so far
    (``completed`` False). The evaluation's history (``Trajectory``) takes at most
    ``record_bytes``: rows are thinned to every ``stride`` steps to fit, which changes what is
    recorded, never the run. A scenario whose start and end rows alone exceed it raises
    ``ScenarioError`` before any work. A network the scenario trains (``ppo``,
    ``recurrent_ppo``) is not the engine's to train: ``nanonav.rl.job`` trains it.
    """
    if scenario.trains:
        raise ScenarioError(
            "robots.policy",
            f"'{scenario.robots.policy}' is a network trained outside the engine "
            "(nanonav.rl.job, a worker that trains); the engine runs its network as policy_from",
        )
    params = kernel_params(scenario, record_bytes)
    _warm_up()
    learning = scenario.learning
    total = scenario.episodes
    run = Run(scenario, params, policy)
    engine_s = 0.0
    eval_s = 0.0
    while run.episode < total:
        evaluating = run.episode >= learning.episodes
        started = time.perf_counter()
        run.advance(CHUNK_ROBOT_STEPS)
        elapsed = time.perf_counter() - started
        engine_s += elapsed
        if evaluating:
            eval_s += elapsed
        if progress is not None:
            where = Progress(run.episode, total, run.step, learning.max_steps)
            if progress(where) is False:
                break

    finished = min(run.episode, learning.episodes)
    curve = run.learning_curve(finished)
    work = {"robot_steps": run.robot_steps, "engine_s": engine_s}
    qtable = None
    if run.params.learn:
        states, actions = qlearning.labels(learning.actions, scenario.communication.model)
        learner = run.learner
        values = learner.q[0] if learning.shared_table else learner.q
        visits = learner.visits[0] if learning.shared_table else learner.visits
        qtable = QTable(states, actions, values.copy(), visits.copy())
    if run.episode < total:
        return SimulationResult(scenario, {}, [], curve, work, None, qtable, completed=False)
    worlds, rows = run.evaluated(eval_s)
    summary, uncertainty = metrics.over_worlds(worlds, scenario.cells.count)
    return SimulationResult(
        scenario, summary, rows, curve, work, run.trajectory(), qtable,
        uncertainty=uncertainty, worlds=worlds, physics=derived_physics(scenario, summary),
    )  # fmt: skip


def derived_physics(scenario: Scenario, summary: dict[str, Any]) -> dict[str, float]:
    """What the active Brownian physics derives from its inputs, and the summary's step counts
    in seconds; empty in the lattice physics."""
    ph = scenario.physics
    if ph.model != "active_brownian":
        return {}
    d_t = ph.diffusion_um2_s or 0.0
    d_r = ph.rotational_diffusion_s or 0.0
    v = ph.swim_speed_um_s
    r = ph.robot_radius_um
    out = {
        "diffusion_um2_s": d_t,
        "rotational_diffusion_s": d_r,
        "persistence_length_um": brownian.persistence_length_um(v, d_r) if d_r else math.inf,
        "peclet_translational": brownian.peclet_translational(v, r, d_t) if d_t else math.inf,
        "peclet_rotational": brownian.peclet_rotational(v, r, d_r) if d_r else math.inf,
        "decay_length_um": math.sqrt(ph.molecule_diffusion_um2_s / ph.decay_rate_s),
        "time_limit_s": scenario.learning.max_steps * ph.step_s,
    }
    for key in ("total_steps", "mean_steps_to_reach"):
        if isinstance(summary.get(key), (int, float)):
            out[key.replace("steps", "time").replace("total_time", "time_to_reach") + "_s"] = (
                float(summary[key]) * ph.step_s
            )
    return {k: v for k, v in out.items() if math.isfinite(v)}
