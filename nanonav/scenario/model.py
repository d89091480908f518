"""The scenario: a complete simulation run, its parts and the rules that relate them, and a
preset's scenario (``preset_scenario``)."""

from __future__ import annotations

import math
from typing import Annotated, Any

from pydantic import (
    Field,
    ValidationError,
    ValidatorFunctionWrapHandler,
    field_validator,
    model_validator,
)
from pydantic_core import PydanticCustomError

from nanonav.physics import MOLECULES_PER_UM3_PER_NM, time_limit_steps
from nanonav.scenario import work as work_model
from nanonav.scenario.base import Part, admits, field_error, whole
from nanonav.scenario.choices import (
    BROWNIAN_POLICIES,
    LATTICE_POLICIES,
    TRAINED_POLICIES,
    PresetName,
)
from nanonav.scenario.limits import (
    BROWNIAN_ALPHA_EXPONENT,
    BROWNIAN_DECISION_INTERVAL_S,
    BROWNIAN_SIGNAL,
    CHECKPOINT_DECISIONS,
    DENSEST_PACKING,
    LARGEST_DECAY_RATE,
    LATTICE_SIGNAL,
    MAX_EXACT_INT,
    MAX_OBSTACLE_VOLUME_FRACTION,
    MAX_ROBOT_VOLUME_FRACTION,
    MAX_SIGNAL_EVERY,
    TRAINING_DECISIONS,
)
from nanonav.scenario.parts import (
    Biomarker,
    Cells,
    Communication,
    Evaluation,
    Learning,
    Obstacles,
    Rewards,
    Robots,
    Space,
)
from nanonav.scenario.physics import Physics, fill_physics
from nanonav.scenario.presets import PRESETS, deep_merge

# Fields that only the lattice physics reads, and what stands for each in active_brownian.
_NOISE = "readings carry the Berg-Purcell noise of the robot's size (physics)"
_FIELD = ("the field is the steady state of physics.secretion_molecules_s, "
          "molecule_diffusion_um2_s and decay_rate_s")  # fmt: skip
LATTICE_ONLY: tuple[tuple[str, str, str], ...] = (
    ("robots", "speed", "robots swim at physics.swim_speed_um_s"),
    ("robots", "radius", "a robot's radius is physics.robot_radius_um"),
    ("robots", "sensing_radius", "an obstacle is sensed by touching it"),
    ("robots", "sensor_baseline", "the gradient is sensed across the body (robot_radius_um)"),
    ("cells", "motion_std", "cells diffuse with physics.cell_diffusion_um2_s"),
    ("obstacles", "motion_std", "obstacles (tissue) stand still"),
    *(("biomarker", name, _FIELD) for name in ("model", "peak", "spread", "emitters_per_cell",
                                                "emitter_scatter", "decay_length", "softening")),
    *(("biomarker", name, _NOISE) for name in ("sensor_noise", "noise_floor",
                                                "detection_threshold")),
)  # fmt: skip


def _steering_by_default(data: Any) -> Any:
    """An active Brownian scenario learns among steering actions unless it says otherwise, and
    a time limit in seconds sets its step limit."""
    if not isinstance(data, dict):
        return data
    physics = data.get("physics")
    if not isinstance(physics, dict) or physics.get("model") != "active_brownian":
        return data
    learning = data.get("learning", {})
    if not isinstance(learning, dict):
        return data
    if "actions" not in learning:
        learning = {**learning, "actions": "steering"}
    physics = fill_physics(physics)
    limit, dt = physics.get("time_limit_s"), physics.get("dt_s")
    if admits(Physics, "time_limit_s", limit) and admits(Physics, "dt_s", dt):
        steps = time_limit_steps(limit, dt)
        # more than learning takes: left out, for Physics to name time_limit_s or dt_s; both
        # given and at odds: kept, for _one_physics to say so
        if admits(Learning, "max_steps", steps):
            learning = {"max_steps": steps, **learning}
    return {**data, "physics": physics, "learning": learning}


def _trained_by_default(data: Any) -> Any:
    """A network the job trains is trained for learning.decisions, not episodes: left out,
    learning.episodes is 0 for it (given, as a study's base may give it for its tabular
    learners, it is left unused)."""
    if not isinstance(data, dict):
        return data
    robots, learning = data.get("robots"), data.get("learning", {})
    if not isinstance(robots, dict) or robots.get("policy") not in TRAINED_POLICIES:
        return data
    if not isinstance(learning, dict) or "episodes" in learning:
        return data
    return {**data, "learning": {**learning, "episodes": 0}}


class Scenario(Part):
    """A complete simulation run: the world, the swarm, the learning and the seed.

    Besides each field's type and bounds, rules relate fields to one another (each field's
    description states its own; a 422 of type ``scenario_rule`` names the field to change):
    epsilon_end at most epsilon_start; obstacles.radius under a quarter and reach_distance under
    half of space.size; obstacles filling at most 30% of the cube; physics.time_limit_s at most
    learning.max_steps' 1,000,000 steps of dt_s; and with policy_from, learning.episodes 0 and
    robots.policy q_learning."""

    preset: PresetName | None = Field(
        None,
        description="Base values; fields given explicitly override the preset's. The paper's: "
        "'paper-single' (Figures 1, 3, 4: one robot, one cell, ten obstacles) and 'paper-swarm' "
        "(Figure 2: 15 robots, 2 cells, 10 obstacles), with the paper's state (exact readings, "
        "cells sensed within 8 units). 'authors-script': the world of the authors' published "
        "script (a 100-unit cube, the robot starting in a corner octant, a sampled Gaussian "
        "field, no walls, no obstacles) with NanoNav's Q-learning. Hard: "
        "'hard-single' and 'hard-swarm', the paper's worlds with honest sensing (a noise floor "
        "of 0.01 and a detection threshold of 0.005 on the readings, cells sensed within 2 "
        "units only) and 30 drifting obstacles. Physical (physics.model active_brownian, µm "
        "and s): 'tumour-microswimmers', one tumour cell (7.5 µm) among 40 tissue obstacles "
        "(5 µm) in a 150 µm cube, 20 robots of 1 µm swimming at 10 µm/s that sense a cell by "
        "touching it and take up space (hard spheres), 60 s; 'tumour-nanorobots', the same "
        "with robots of 0.2 µm; "
        "'tumour-passive', robots of 1 µm that do not swim (uncontrolled, speed 0); "
        "'tumour-signals', the same tissue with 5 cells that each need 3 payloads and 40 "
        "robots of 1 µm following 'gradient': a robot bound to a cell releases an attractant "
        "(10,000 molecules/s, D 100 µm²/s, decay 0.1 /s) that the others count as they count "
        "the biomarker, and follow where the biomarker is at trace level; "
        "'alonso-kirkegaard', the setting of Alonso & Kirkegaard (PNAS Nexus 2024) in three "
        "dimensions: one robot of 0.5 µm at 5 µm/s, D_R 0.025 1/s, no translational noise, "
        "deciding and counting molecules every 0.1 s, turning up to π per decision, one still "
        "source of field length 100 µm secreting 21,500 molecules/s (their weakest, N = 1e4, "
        "counted alike 50 µm away), reached within 10.5 µm, 25.6 s. The "
        "swarm's: 'diffuse-tumour', 20 small cells that each need 3 payloads, scattered through "
        "a 100-unit cube, each shedding a faint, short-range marker (spread 3, a noise floor "
        "and a detection threshold), among 20 drifting obstacles; 100 robots that take up space "
        "and follow 'rule'; cells sensed within 2 units; 1,000 steps. Set "
        "communication.model to let them signal.",
    )
    seed: int = Field(
        0,
        ge=0,
        le=MAX_EXACT_INT,
        description="Seed of every random draw; the same scenario and seed give bit-identical "
        "results. Left out of POST /jobs, the server draws one (each submit a new sample) and "
        "stores it in the resolved scenario; `nanonav run` uses 0.",
    )
    space: Space = Space()
    cells: Cells = Cells()
    biomarker: Biomarker = Biomarker()
    obstacles: Obstacles = Obstacles()
    robots: Robots = Robots()
    learning: Learning = Learning()
    rewards: Rewards = Rewards()
    evaluation: Evaluation = Evaluation()
    physics: Physics = Physics()
    communication: Communication = Communication()
    reach_distance: float = Field(
        0.5,
        gt=0.0,
        le=100.0,
        description="A robot within this distance of a cell, length units, has reached it and "
        "stops; less than half of space.size.",
    )
    policy_from: (
        Annotated[int, Field(ge=1, le=MAX_EXACT_INT)]
        | Annotated[str, Field(pattern=r"^policy-[1-9][0-9]{0,14}$")]
        | None
    ) = Field(
        None,
        description="The learned policy this run evaluates in this scenario's worlds without "
        "training (learning.episodes must be 0 and robots.policy q_learning, the learner whose "
        "policy it is): the id of a succeeded Q-learning job, whose learned table it is, or "
        "'policy-<id>', a table or a network made elsewhere and sent to POST /policies. A "
        "table's action set and state layout must be this scenario's (learning.actions, "
        "communication.model); a shared table may drive robots that each learn their own, a "
        "per-robot table needs as many robots. A network must choose among this scenario's "
        "actions from what its robots observe (the physics and communication.model it was "
        "trained in); it decides for every robot of every evaluation world in one call, each "
        "decision held for learning.decision_interval_s.",
    )

    @field_validator("policy_from", mode="wrap")
    @classmethod
    def _names_a_job_or_a_policy(cls, value: Any, handler: ValidatorFunctionWrapHandler) -> Any:
        """One error saying what may be named, rather than one per kind of name."""
        try:
            return handler(whole(value))
        except ValidationError:
            raise PydanticCustomError(
                "policy_from",
                "must be a job's id (an integer from 1) or a policy's name as POST /policies "
                "answers it, 'policy-<id>'; not {value}",
                {"value": repr(value)[:60]},
            ) from None

    @model_validator(mode="before")
    @classmethod
    def _apply_preset(cls, data: Any) -> Any:
        if isinstance(data, dict) and isinstance(data.get("preset"), str):
            base = PRESETS.get(data["preset"])
            if base is not None:
                data = deep_merge(base, data)
        return _trained_by_default(_steering_by_default(data))

    @model_validator(mode="after")
    def _one_physics(self) -> Scenario:
        """Each physics takes its own policies and action set, and a field that only the other
        has a use for is refused rather than ignored."""
        brownian = self.physics.model == "active_brownian"
        allowed = BROWNIAN_POLICIES if brownian else LATTICE_POLICIES
        if self.robots.policy not in allowed:
            raise field_error(
                "Scenario", ("robots", "policy"), self.robots.policy,
                f"is not a policy of physics.model '{self.physics.model}', which takes "
                + ", ".join(sorted(allowed)),
            )  # fmt: skip
        if (self.learning.actions == "steering") != brownian:
            wanted = "steering" if brownian else "behaviors or directions"
            raise field_error(
                "Scenario", ("learning", "actions"), self.learning.actions,
                f"physics.model '{self.physics.model}' takes the action set {wanted}",
            )  # fmt: skip
        if brownian and self.physics.time_limit_s is not None and self.physics.dt_s:
            steps = time_limit_steps(self.physics.time_limit_s, self.physics.dt_s)
            if self.learning.max_steps != steps:
                raise field_error(
                    "Scenario", ("learning", "max_steps"), self.learning.max_steps,
                    f"physics.time_limit_s sets it: {steps} steps of dt_s; give one of the two",
                )  # fmt: skip
        self._decision_interval_fits(brownian)
        self._horizon_fits(brownian)
        if brownian:
            # a value other than the default: a resolved scenario, which lists every field,
            # validates again as it was
            for part, name, instead in LATTICE_ONLY:
                section = getattr(self, part)
                if getattr(section, name) != type(section).model_fields[name].default:
                    raise field_error(
                        "Scenario", (part, name), getattr(section, name),
                        f"has no use in physics.model 'active_brownian': {instead}",
                    )  # fmt: skip
            if self.reach_distance != type(self).model_fields["reach_distance"].default:
                raise field_error(
                    "Scenario", ("reach_distance",), self.reach_distance,
                    "has no use in physics.model 'active_brownian': a robot reaches a cell "
                    "when their surfaces touch (physics.robot_radius_um, cell_radius_um)",
                )  # fmt: skip
        return self

    def _brownian_learning(self, name: str, brownian: bool, instead: str) -> float | None:
        """learning.<name>, a field of active Brownian learning (None if not given), refused in
        the lattice saying what to do ``instead``."""
        value: float | None = getattr(self.learning, name)
        if value is not None and not brownian:
            raise field_error(
                "Scenario", ("learning", name), value,
                f"has no use in physics.model 'lattice': {instead}",
            )  # fmt: skip
        return value

    def _decision_interval_fits(self, brownian: bool) -> None:
        """A decision interval is a whole number of steps of dt_s, from one step to the
        episode's time limit, and only active Brownian robots take one."""
        interval = self._brownian_learning(
            "decision_interval_s", brownian, "a lattice robot decides every step"
        )
        if interval is None:
            return
        where = ("learning", "decision_interval_s")
        dt = self.physics.step_s
        steps = interval / dt
        whole = round(steps)
        if steps < 1.0 - 1e-9:
            raise field_error(
                "Scenario", where, interval,
                f"is shorter than one step (physics.dt_s {dt:g} s): a robot decides at most "
                "once a step",
            )  # fmt: skip
        if abs(steps - whole) > 1e-9 * max(1.0, steps):
            below, above = math.floor(steps) * dt, math.ceil(steps) * dt
            raise field_error(
                "Scenario", where, interval,
                f"is not a whole number of steps of physics.dt_s {dt:g} s: {below:.6g} or "
                f"{above:.6g} would do",
            )  # fmt: skip
        if whole > self.learning.max_steps:
            raise field_error(
                "Scenario", where, interval,
                f"is longer than the episode ({self.learning.max_steps} steps of dt_s {dt:g} s, "
                f"{self.learning.max_steps * dt:g} s)",
            )  # fmt: skip

    def _horizon_fits(self, brownian: bool) -> None:
        """A horizon in seconds is active Brownian robots' discount, given instead of gamma."""
        horizon = self._brownian_learning(
            "horizon_s", brownian, "give learning.gamma, the discount per step"
        )
        if horizon is None:
            return
        where = ("learning", "horizon_s")
        if self.learning.gamma != type(self.learning).model_fields["gamma"].default:
            raise field_error(
                "Scenario", where, horizon,
                f"and learning.gamma ({self.learning.gamma:g}) both set the discount: give one "
                "of the two",
            )  # fmt: skip

    @property
    def discount(self) -> float:
        """The discount of one decision: learning.gamma, or from learning.horizon_s over the
        decision interval."""
        horizon = self.learning.horizon_s
        if horizon is None:
            return self.learning.gamma
        return math.exp(-self.decision_steps * self.physics.step_s / horizon)

    @property
    def decision_steps(self) -> int:
        """Steps of dt_s between two decisions by action number (learning.decision_interval_s;
        1: every step)."""
        if self.physics.model != "active_brownian":
            return 1
        interval = self.learning.decision_interval_s
        if interval is None:
            steps = round(BROWNIAN_DECISION_INTERVAL_S / self.physics.step_s)
            return max(1, min(steps, self.learning.max_steps))
        return max(1, round(interval / self.physics.step_s))

    @property
    def alpha_exponent(self) -> float:
        """The visits schedule's exponent: learning.alpha_exponent, or its physics' default."""
        if self.learning.alpha_exponent is not None:
            return self.learning.alpha_exponent
        return BROWNIAN_ALPHA_EXPONENT if self.physics.model == "active_brownian" else 1.0

    @property
    def step_rewards(self) -> tuple[float, float]:
        """The rewards of one step, and of one blocked step (rewards.step, rewards.collision): in
        active_brownian they are rates, so dt_s times them."""
        per = self.physics.step_s if self.physics.model == "active_brownian" else 1.0
        return self.rewards.step * per, self.rewards.collision * per

    @model_validator(mode="after")
    def _communication_fits(self) -> Scenario:
        """Each physics takes the signal's rates in its own units; a learner that uses signals
        needs an action set that can follow them."""
        comm = self.communication
        fields = type(comm).model_fields
        brownian = self.physics.model == "active_brownian"
        other = LATTICE_SIGNAL if brownian else BROWNIAN_SIGNAL
        for name in other:
            if getattr(comm, name) != fields[name].default:
                instead = BROWNIAN_SIGNAL if brownian else LATTICE_SIGNAL
                raise field_error(
                    "Scenario", ("communication", name), getattr(comm, name),
                    f"has no use in physics.model '{self.physics.model}', which takes "
                    + ", ".join(instead),
                )  # fmt: skip
        if (
            comm.model != "none"
            and self.robots.policy == "q_learning"
            and self.learning.actions == "directions"
        ):
            raise field_error(
                "Scenario", ("learning", "actions"), self.learning.actions,
                f"cannot follow communication.model '{comm.model}': use behaviors, whose "
                "follow_signal action does",
            )  # fmt: skip
        return self

    @model_validator(mode="after")
    def _robots_fit(self) -> Scenario:
        """Robots that take up space must have room to start apart."""
        if not self.robots.exclusion:
            return self
        radius = self.robot_radius
        volume = self.robots.count * 4.0 / 3.0 * math.pi * radius**3
        corner = self.robots.start == "corner"
        # robots start in the corner octant (a quarter of the side each way), or anywhere
        room = (self.space.size / 4 if corner else self.space.size) ** 3
        if volume > MAX_ROBOT_VOLUME_FRACTION * room:
            where = "the corner they start in" if corner else "the space"
            raise field_error(
                "Scenario", ("robots", "count"), self.robots.count,
                f"robots of radius {radius:g} that take up space would fill more than "
                f"{MAX_ROBOT_VOLUME_FRACTION:.0%} of {where}",
            )  # fmt: skip
        return self

    @model_validator(mode="after")
    def _room_at_a_cell(self) -> Scenario:
        """Robots that take up space and deliver to a cell must fit within reach of it: at most
        the densest packing of spheres of their radius in the ball of the reach distance plus
        a radius round the cell's centre (a bound, never tight)."""
        capacity = self.cells.capacity
        if not self.robots.exclusion or capacity is None:
            return self
        r = self.robot_radius
        reach = (
            self.physics.robot_radius_um + self.physics.cell_radius_um
            if self.physics.model == "active_brownian"
            else self.reach_distance
        )
        room = math.floor(DENSEST_PACKING * ((reach + r) / r) ** 3)
        if capacity > room:
            raise field_error(
                "Scenario", ("cells", "capacity"), capacity,
                f"at most {room} robots of radius {r:g} that take up space fit within reach of "
                "a cell: a larger capacity could never be delivered",
            )  # fmt: skip
        return self

    @property
    def robot_radius(self) -> float:
        """A robot's radius in the scenario's length unit: robots.radius, or in the active
        Brownian physics physics.robot_radius_um."""
        if self.physics.model == "active_brownian":
            return self.physics.robot_radius_um
        return self.robots.radius

    @model_validator(mode="after")
    def _learned_policy(self) -> Scenario:
        if self.policy_from is None:
            return self
        if self.robots.policy != "q_learning":
            raise field_error(
                "Scenario", ("robots", "policy"), self.robots.policy,
                "policy_from needs q_learning: only a learned policy can be evaluated",
            )  # fmt: skip
        if self.learning.episodes != 0:
            raise field_error(
                "Scenario", ("learning", "episodes"), self.learning.episodes,
                "must be 0 with policy_from: a learned policy is evaluated, not trained further",
            )  # fmt: skip
        return self

    @property
    def trains(self) -> bool:
        """Whether the job trains a network (ppo, recurrent_ppo): a worker that trains runs it."""
        return self.robots.policy in TRAINED_POLICIES

    @property
    def training_decisions(self) -> int:
        """The decisions a network the job trains is trained for (0 when it trains none)."""
        if not self.trains:
            return 0
        return self.learning.decisions or TRAINING_DECISIONS

    @property
    def checkpoint_every(self) -> int:
        """Decisions between two checkpoints of a network's training."""
        return self.learning.checkpoint_decisions or CHECKPOINT_DECISIONS

    def network_scenario(self) -> Scenario:
        """The scenario a network is trained and evaluated in: its robots take their actions
        from outside, as a network given by policy_from does (robots.policy q_learning, no
        episodes of tabular learning, none of the trainer's fields)."""
        data = self.model_dump()
        data["preset"] = None
        data["robots"]["policy"] = "q_learning"
        data["learning"].update(episodes=0, decisions=None, checkpoint_decisions=None)
        return Scenario.model_validate(data)

    @model_validator(mode="after")
    def _fits_in_space(self) -> Scenario:
        half = self.space.size / 2
        radius = self.obstacles.radius
        if radius >= half / 2:
            raise field_error(
                "Scenario", ("obstacles", "radius"), radius,
                "must be less than a quarter of space.size",
            )  # fmt: skip
        sphere = 4.0 / 3.0 * math.pi * radius**3
        if self.obstacles.count * sphere > MAX_OBSTACLE_VOLUME_FRACTION * self.space.size**3:
            raise field_error(
                "Scenario", ("obstacles", "count"), self.obstacles.count,
                f"obstacles of this radius would fill more than "
                f"{MAX_OBSTACLE_VOLUME_FRACTION:.0%} of the space",
            )  # fmt: skip
        if self.reach_distance >= half:
            raise field_error(
                "Scenario", ("reach_distance",), self.reach_distance,
                "must be less than half of space.size",
            )  # fmt: skip
        return self

    @property
    def signal_rates(self) -> tuple[float, float, float]:
        """The signal's diffusion coefficient (length^2), decay rate and one bound robot's
        release (concentration x length^3; in active_brownian nM µm³), per engine step."""
        comm = self.communication
        if self.physics.model == "active_brownian":
            dt = self.physics.step_s
            return (
                comm.diffusion_um2_s * dt,
                comm.decay_rate_s * dt,
                comm.release_molecules_s * dt / MOLECULES_PER_UM3_PER_NM,
            )
        decay = -math.log1p(-comm.decay_rate) if comm.decay_rate < 1.0 else LARGEST_DECAY_RATE
        return comm.diffusion, decay, comm.release_rate

    @property
    def signal_solver_steps(self) -> tuple[int, int]:
        """(engine steps per update of the signal's grid, solver steps per update). The explicit
        solver is stable and keeps every node non-negative while dt (6 D / h^2 + k) <= 1; it
        takes half that (at the bound a release hops between the lattice's two halves, a
        checkerboard): the largest whole number of engine steps (at most
        ``MAX_SIGNAL_EVERY``), or one engine step split into the fewest such solver steps."""
        diffusion, decay, _ = self.signal_rates
        spacing = self.space.size / self.communication.nodes_per_axis
        rate = 6.0 * diffusion / spacing**2 + decay
        stable = 0.5 / rate if rate > 0 else math.inf
        if stable >= MAX_SIGNAL_EVERY:
            return MAX_SIGNAL_EVERY, 1
        if stable >= 1.0:
            return math.floor(stable), 1
        return 1, math.ceil(1.0 / stable)

    @property
    def robot_steps_budget(self) -> int:
        """The most robot-steps this scenario can cost: robots x max_steps x (training episodes
        + evaluation worlds), and a trained network's decisions x the steps each holds."""
        training = self.training_decisions * self.decision_steps
        return self.robots.count * self.learning.max_steps * self.episodes + training

    @property
    def episodes(self) -> int:
        """Episodes a run has in all: training, then evaluation (a network the job trains
        trains for decisions, not episodes: its evaluation alone)."""
        if self.trains:
            return self.evaluation.worlds
        return self.learning.episodes + self.evaluation.worlds

    @property
    def sources(self) -> int:
        """Point sources of the field: the cells, or their emitters for the inverse-square model."""
        if self.biomarker.model in ("inverse_square", "sampled_gaussian"):
            return self.cells.count * self.biomarker.emitters_per_cell
        return self.cells.count

    @property
    def robot_step_overhead(self) -> float:
        """C, the work of one robot's step besides its scans and field terms (``work``)."""
        return work_model.robot_step_overhead(self)

    @property
    def work(self) -> int:
        """The most this scenario can cost, in work units (``nanonav.scenario.work``)."""
        return work_model.most_work(self)

    def work_for(self, robot_steps: int, steps: int, episodes: int, evaluation_steps: int) -> int:
        """The work of a run of this scenario that took these robot-steps, steps, episodes and
        evaluation steps (``nanonav.scenario.work``)."""
        return work_model.work_for(self, robot_steps, steps, episodes, evaluation_steps)


def preset_scenario(name: str, **overrides: Any) -> Scenario:
    """A preset's scenario, with ``overrides`` applied on top (keys as in the JSON schema)."""
    return Scenario.model_validate({"preset": name, **overrides})
