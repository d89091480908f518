"""The scenario: one validated, documented description of a simulation run.

The same schema is used unchanged by the library, the ``nanonav`` command and the REST API.
Every field has a default and a bound, unknown keys are rejected, and a ``preset`` supplies base
values that explicit fields override. Two physics: ``lattice`` (the paper's), where lengths are in
simulation units (the paper's cube is 50 units a side), times in steps and concentrations in
arbitrary units relative to ``biomarker.peak``; and ``active_brownian``, where every length is in
µm, every time in s (a step is ``physics.dt_s``) and every concentration in nM, and the
quantities only it has carry their unit in their name (``physics``).
"""

from __future__ import annotations

import math
import operator
from typing import Annotated, Any, Literal, get_args

from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    ValidationError,
    ValidatorFunctionWrapHandler,
    field_validator,
    model_validator,
)
from pydantic_core import InitErrorDetails, PydanticCustomError

PresetName = Literal[
    "paper-single",
    "paper-swarm",
    "authors-script",
    "hard-single",
    "hard-swarm",
    "tumour-microswimmers",
    "tumour-nanorobots",
    "tumour-passive",
    "tumour-signals",
    "diffuse-tumour",
    "alonso-kirkegaard",
]
FieldModel = Literal["gaussian", "inverse_square", "diffusion", "sampled_gaussian"]
Schedule = Literal["sequential", "simultaneous"]
# How an agent outside steers an active Brownian robot: by the action set's numbers, or by a
# continuous turn (side, up) in the robot's body frame (``nanonav.engine.worlds.Worlds``).
Steering = Literal["discrete", "continuous"]
STEERINGS: tuple[Steering, ...] = ("discrete", "continuous")
RobotStart = Literal["anywhere", "corner"]
Policy = Literal[
    "q_learning",
    "gradient",
    "run_and_tumble",
    "rule",
    "simple_rule",
    "random",
    "uncontrolled",
    "exact_gradient",
    "steer_and_tumble",
    "blind_tumble",
]
AlphaSchedule = Literal["constant", "visits"]
ActionSet = Literal["behaviors", "directions", "steering"]
PhysicsModel = Literal["lattice", "active_brownian"]
Sensor = Literal["each_step", "counted"]
# sensor 'counted': the integration time filled in, s (Alonso & Kirkegaard, PNAS Nexus 2024:
# their receptors count molecules over a step of 0.1 s), unless r^2 / D_m is longer
DEFAULT_INTEGRATION_TIME_S = 0.1
CommunicationModel = Literal["none", "attractant", "attractant_repellent", "broadcast"]
# What each physics runs: the paper's lattice moves choose a direction; an active Brownian robot
# can only steer its own diffusing heading.
LATTICE_POLICIES = frozenset({"q_learning", "gradient", "run_and_tumble", "rule", "simple_rule",
                              "random"})  # fmt: skip
BROWNIAN_POLICIES = frozenset({"q_learning", "uncontrolled", "run_and_tumble", "gradient",
                               "exact_gradient", "steer_and_tumble", "blind_tumble"})  # fmt: skip

MAX_OBSTACLE_VOLUME_FRACTION = 0.3
DENSEST_PACKING = math.pi / math.sqrt(18)  # Kepler's bound: equal spheres fill at most 74 %
MAX_ROBOT_VOLUME_FRACTION = 0.1  # robots that take up space start apart at random: room to spare
# The signal's rates in each physics' units (communication): each physics refuses the other's.
LATTICE_SIGNAL = ("diffusion", "decay_rate", "release_rate")
BROWNIAN_SIGNAL = ("diffusion_um2_s", "decay_rate_s", "release_molecules_s")
# The largest seed or id: every integer up to it is exact in a JSON number whatever the client
# (a double, as I-JSON, RFC 7493, advises), so what a client sends is what is stored.
MAX_EXACT_INT = 2**53 - 1
MAX_STEPS = 1_000_000  # learning.max_steps: the longest episode
# The active Brownian learner's defaults, chosen on design seeds 5000-5007 at robot radii 0.5, 1,
# 2 and 5 µm (benchmarks/decision_interval.py; docs/explanation/learning.md, "Decisions in
# physical time"): a decision every second, and the visits schedule's exponent 0.6 (1 left the
# table unsettled there).
BROWNIAN_DECISION_INTERVAL_S = 1.0
BROWNIAN_ALPHA_EXPONENT = 0.6

# What the engine's operations cost, in work units: nanoseconds of one core of the machine they
# were fitted on (``python benchmarks/cost.py`` measures how well they track run time). Another
# machine scales them all alike.
# C: one robot's step besides its scans and field terms (sense noise, state, choice, move, learn)
WORK_ROBOT_STEP = {"behaviors": 270, "directions": 160, "steering": 270, "baseline": 95}
WORK_STEP = 195  # one step besides its robots: the loops over the swarm
WORK_PAIR = 1.25  # one distance test between two points (say, a robot and an obstacle)
WORK_DRAW = 32  # one random point, direction or offset (three normal draws)
WORK_PLACE = 2.5  # one source moved with its cell
# one source's term of the field at one point: an exp for these two, a division for the
# inverse-square emitters (summed in a fixed order of lanes, which the compiler does not
# vectorise: 2.6 ns a term here)
WORK_SOURCE = {"gaussian": 6.5, "diffusion": 6.5, "inverse_square": 2.6, "sampled_gaussian": 6.5}
# The swarm's: per active robot-step, the neighbour search of robots that take up space, a
# reading of the signal grid, or keeping the radio's cell list current; per grid node and
# solver step, the signal's diffusion; per robot and grid update, its release (if bound).
WORK_EXCLUSION = 120
WORK_SIGNAL_READ = 60
WORK_RELIST = 15
WORK_NODE = 1.5
WORK_RELEASE = 4
# The signal's grid is updated at most every this many engine steps, so it keeps up with robots.
MAX_SIGNAL_EVERY = 10
LARGEST_DECAY_RATE = 50.0  # per step: a decay_rate of 1 (all of it) taken as this rate


BOLTZMANN_J_K = 1.380649e-23  # exact since the 2019 SI
AVOGADRO_PER_MOL = 6.02214076e23  # exact since the 2019 SI
MOLECULES_PER_UM3_PER_NM = AVOGADRO_PER_MOL * 1e-9 / 1e15  # 1 nM in molecules per µm³: 0.6022


def stokes_einstein_um2_s(temperature_k: float, viscosity_mpa_s: float, radius_um: float) -> float:
    """D_T = k_B T / (6 pi eta R) of a sphere, µm²/s."""
    return (
        BOLTZMANN_J_K
        * temperature_k
        / (6 * math.pi * viscosity_mpa_s * 1e-3 * radius_um * 1e-6)
        * 1e12
    )


def stokes_einstein_debye_s(
    temperature_k: float, viscosity_mpa_s: float, radius_um: float
) -> float:
    """D_R = k_B T / (8 pi eta R^3) of a sphere, 1/s."""
    return (
        BOLTZMANN_J_K
        * temperature_k
        / (8 * math.pi * viscosity_mpa_s * 1e-3 * (radius_um * 1e-6) ** 3)
    )


def whole(value: Any) -> Any:
    """A number with no fraction, such as 5.0, as the integer JSON Schema takes it for."""
    if isinstance(value, float) and value.is_integer():
        return int(value)
    return value


def integer_fields(model: type[BaseModel]) -> frozenset[str]:
    """The fields of ``model`` that hold an integer (or null)."""
    return frozenset(
        name
        for name, field in model.model_fields.items()
        if field.annotation is int or set(get_args(field.annotation)) == {int, type(None)}
    )


class ScenarioError(ValueError):
    """A scenario that passed validation but cannot be realised (say, obstacles that leave no
    room); ``field`` is the dotted name of the field to change."""

    def __init__(self, field: str, message: str) -> None:
        super().__init__(f"{field}: {message}")
        self.field = field
        self.message = message

    def __reduce__(self) -> tuple[type[ScenarioError], tuple[str, str]]:
        # Rebuilt from both arguments, so it crosses to and from worker processes intact.
        return type(self), (self.field, self.message)


def _field_error(model: str, loc: tuple[str, ...], value: Any, message: str) -> ValidationError:
    """A validation error that names the field at fault, for rules that span several fields."""
    error = PydanticCustomError("scenario_rule", message)
    return ValidationError.from_exception_data(
        model, [InitErrorDetails(type=error, loc=loc, input=value)]
    )


class _Part(BaseModel):
    """Strict, as JSON Schema means its types: a number is not true, false or "5"; an integer
    may stand where a decimal number is expected, and 5.0 where an integer is."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False, strict=True)

    @model_validator(mode="before")
    @classmethod
    def _whole_numbers(cls, data: Any) -> Any:
        if not isinstance(data, dict):
            return data
        integers = integer_fields(cls)
        return {key: whole(value) if key in integers else value for key, value in data.items()}


class Space(_Part):
    """The tissue volume: a cube centred at the origin whose walls reflect everything inside."""

    size: float = Field(
        50.0,
        ge=1.0,
        le=1000.0,
        description="Side of the cube, in length units (µm in physics.model active_brownian; "
        "paper 2.4: 50). The cube spans "
        "[-size/2, size/2] on every axis. At least 1 (in µm: less than a cell).",
    )
    walls: bool = Field(
        True,
        description="true: the cube's walls reflect robots, cells and obstacles. false: the "
        "cube only says where things start, and anything may leave it (as in the authors' "
        "published script, whose cell drifts freely).",
    )


class Cells(_Part):
    """Cancer cells: the targets, which drift as a random walk (paper 3.1) and shed biomarkers."""

    count: int = Field(1, ge=1, le=100, description="Number of cancer cells.")
    motion_std: float = Field(
        0.2,
        ge=0.0,
        le=10.0,
        description="Standard deviation of the cells' random walk, length units per axis per "
        "step: each step a cell moves by N(0, motion_std) on x, y and z. 0 keeps cells still.",
    )
    start_extent: float = Field(
        0.8,
        gt=0.0,
        le=1.0,
        description="Cells start uniformly within this share of the half-width of the space on "
        "every axis (1: anywhere in the cube).",
    )
    capacity: int | None = Field(
        None,
        ge=1,
        le=100_000,
        description="Payloads a cell takes (the drug it needs): each robot that reaches an "
        "untreated cell delivers one and stays bound to it; the capacity-th delivery treats the "
        "cell, and robots that arrive later are turned away and keep searching (a treated cell "
        "is no longer a target: not sensed, not reached). An episode ends when every cell is "
        "treated. null: no cell is ever treated (the paper's).",
    )
    treated_secretion: float = Field(
        0.0,
        ge=0.0,
        le=1.0,
        description="Share of its biomarker a treated cell still sheds (0: it stops).",
    )


class Biomarker(_Part):
    """The biomarker concentration field the robots sense (paper 2.1, 2.2 and 2.6)."""

    model: FieldModel = Field(
        "gaussian",
        description="'gaussian': eq. 2.1, C = sum over cells of peak*exp(-r^2/(2*spread^2)), "
        "gradient eq. 2.2. 'inverse_square': eq. 2.6, C = sum over point emitters of B/d^2 with "
        "B = peak/emitters_per_cell, softened to B/(d^2 + softening^2). 'diffusion': the steady "
        "state of a source that diffuses and decays, C = peak*exp(-r/decay_length)/r per cell "
        "(peak = Q/(4*pi*D)), with r softened to sqrt(r^2 + softening^2). "
        "'sampled_gaussian': the authors' published script: the mean over emitters_per_cell "
        "points, redrawn every step uniformly within emitter_scatter of the cell on each axis, "
        "of peak*exp(-d^2/(2*spread^2)); the script's exp(-d^2/40^2) is spread = 28.28.",
    )
    peak: float = Field(
        1.0,
        gt=0.0,
        le=1e6,
        description="Source strength: rho_0 of eq. 2.1 (the concentration at a cell), the total "
        "of the B_i of eq. 2.6 over one cell's emitters, or Q/(4*pi*D) of the diffusion model.",
    )
    spread: float = Field(
        10.0,
        ge=0.01,
        le=1000.0,
        description="sigma of eq. 2.1, length units: how far the Gaussian field reaches. At "
        "least 0.01, the smallest robot's radius: a narrower field is a point.",
    )
    emitters_per_cell: int = Field(
        50,
        ge=1,
        le=1000,
        description="Point emitters around each cell, for the inverse-square model (eq. 2.6) "
        "and the sampled Gaussian; they move with their cell.",
    )
    emitter_scatter: float = Field(
        1.0,
        ge=0.0,
        le=100.0,
        description="How far emitters lie from their cell, length units per axis: the "
        "standard deviation of their offsets (inverse-square model) or the half-width of the "
        "uniform box they are redrawn in every step (sampled Gaussian).",
    )
    decay_length: float = Field(
        10.0,
        ge=0.01,
        le=1e4,
        description="lambda of the diffusion model, length units: sqrt(D/k) for diffusivity D "
        "and decay rate k. Larger values reach farther. At least 0.01, the smallest robot's "
        "radius: a shorter field is a point.",
    )
    softening: float = Field(
        0.5,
        ge=1e-6,
        le=100.0,
        description="Length, in units, that softens the inverse-square and diffusion fields near "
        "their sources so that nothing divides by zero; at least 1e-6, so that the field at a "
        "source stays finite.",
    )
    sensor_noise: float = Field(
        0.0,
        ge=0.0,
        le=1.0,
        description="Relative Gaussian noise on every reading a robot takes: a sensed value v "
        "becomes v*(1 + N(0, sensor_noise)), for the concentration and each gradient component.",
    )
    noise_floor: float = Field(
        0.0,
        ge=0.0,
        le=1e6,
        description="Additive Gaussian noise on every concentration reading, in concentration "
        "units: what a real sensor reads when there is nothing to read. The gradient is sensed "
        "as the difference of two readings robots.sensor_baseline apart, each with its own "
        "noise, so each of its components carries sqrt(2) * noise_floor / sensor_baseline. Far "
        "from a cell the signal sinks below this floor and the gradient's direction is lost.",
    )
    detection_threshold: float = Field(
        0.0,
        ge=0.0,
        le=1e6,
        description="A (noisy) concentration reading below this counts as nothing: the robot "
        "senses no concentration and no gradient.",
    )


class Obstacles(_Part):
    """Spherical biological barriers (paper 2.4 and 2.6) placed at random, clear of cells and
    robot starts. A move that would end inside one is blocked and counts as a collision."""

    count: int = Field(
        10,
        ge=0,
        le=1000,
        description="Number of obstacles. Together they may fill at most 30% of the cube's "
        "volume (count x 4/3 pi radius^3 <= 0.3 x space.size^3).",
    )
    radius: float = Field(
        1.5,
        gt=0.0,
        le=100.0,
        description="Obstacle radius, length units (µm in active_brownian); less than a quarter "
        "of space.size.",
    )
    motion_std: float = Field(
        0.0,
        ge=0.0,
        le=10.0,
        description="Per-axis standard deviation of the obstacles' random drift, length units "
        "per step (paper 2.6, dynamic environment). 0 keeps them still.",
    )


class Robots(_Part):
    """The nanorobot swarm. Each robot senses only locally: the concentration and its gradient
    where it is, and obstacles and cells within ``sensing_radius``."""

    count: int = Field(1, ge=1, le=100_000, description="Number of robots.")
    speed: float = Field(
        0.5, gt=0.0, le=100.0, description="Distance a robot moves in one step, length units."
    )
    sensing_radius: float = Field(
        8.0,
        ge=0.0,
        le=10_000.0,
        description="Range, length units, within which a robot detects obstacles (their surfaces).",
    )
    cell_sensing_radius: float = Field(
        8.0,
        ge=0.0,
        le=10_000.0,
        description="Range, length units, within which a robot senses where a cell is (in "
        "active_brownian: µm from the robot's surface to the cell's, its receptors' range; the "
        "paper's state holds the distance to cells). 0: a robot learns of a cell only by "
        "touching it, and must find it from the biomarker alone.",
    )
    start: RobotStart = Field(
        "anywhere",
        description="Where robots start: 'anywhere' in the cube (away from the walls by a "
        "twentieth of its half-width), or 'corner', the octant at (-,-,-): every coordinate "
        "within [-size/2, -size/4], as in the authors' published script.",
    )
    sensor_baseline: float = Field(
        0.5,
        ge=0.01,
        le=100.0,
        description="Spacing, length units, of the concentration readings whose differences "
        "give the sensed gradient (the robot's size, so at least 0.01 as its radius): see "
        "biomarker.noise_floor.",
    )
    policy: Policy = Field(
        "q_learning",
        description="'q_learning': tabular Q-learning (paper 2.5, 2.7). Baselines: 'gradient' "
        "climbs the sensed gradient, sliding along an obstacle's surface rather than into it, "
        "and keeps its heading where it senses no gradient; 'run_and_tumble' keeps its heading "
        "while the reading rises and turns to a random heading otherwise (bacterial "
        "chemotaxis); 'rule' is the strongest fixed rule found for the paper's sensors, the bar a "
        "learner must clear: advance on a sensed cell; else, on a reading above the 'mid' "
        "level, run and tumble (straight on while the reading rises, a random heading when it "
        "does not); else climb the gradient as 'gradient' does; 'simple_rule' advances on a "
        "sensed cell, else climbs the gradient; 'random' walks at random. With a "
        "communication model, 'rule' also follows what it receives where it senses no cell and "
        "no biomarker above the 'mid' level: up an attractant while it rises, down a "
        "repellent, toward a message's position. In physics 'active_brownian': 'uncontrolled' "
        "never steers; 'run_and_tumble' tumbles (physics.tumble_rate_s, tumble_rate_rising_s); "
        "'gradient' steers up the sensed gradient; 'steer_and_tumble' steers up the sensed "
        "gradient and tumbles as run_and_tumble does; 'blind_tumble' tumbles at "
        "physics.tumble_rate_s whatever it reads, a searcher that uses no information (the "
        "baseline that tells steering from reorienting); 'exact_gradient' steers up the true "
        "gradient (an upper bound no robot has).",
    )
    exclusion: bool = Field(
        False,
        description="Robots take up space: no two overlap (their centres stay two radii "
        "apart), a move into another robot is refused as one into an obstacle would be (in "
        "active_brownian, hard spheres: it stops at contact and slides on), and "
        "counts as a bump (neighbours are found in a cell list, O(robots) a step). Bound robots "
        "(delivered) keep their place. false: robots pass through each other (the paper's).",
    )
    schedule: Schedule = Field(
        "sequential",
        description="The order of a step's phases across robots (PettingZoo's names): "
        "'sequential' (its AEC order, the paper's): robot i perceives, decides and acts before "
        "robot i + 1 perceives, so it sees what the robots before it did in the same step (a "
        "cell treated, a message sent, a place taken); 'simultaneous' (its parallel order): "
        "every robot perceives, then every robot acts. With one robot the two are the same. "
        "The environments step as their API says: NanoNavAECEnv sequentially, "
        "NanoNavParallelEnv simultaneously.",
    )
    radius: float = Field(
        0.25,
        ge=0.01,
        le=100.0,
        description="Radius of a robot, length units, for exclusion (in active_brownian: "
        "physics.robot_radius_um); at least 0.01, as physics.robot_radius_um (10 nm).",
    )


class Learning(_Part):
    """Tabular Q-learning (paper 2.5 and 2.7): eq. 2.7 updates, epsilon-greedy exploration with
    epsilon decaying per episode."""

    episodes: int = Field(
        50,
        ge=0,
        le=100_000,
        description="Training episodes, each in a fresh world drawn from the seed. The greedy "
        "evaluation (evaluation.worlds episodes) follows them. Baseline policies run the same "
        "episodes as trials.",
    )
    max_steps: int = Field(1000, ge=1, le=MAX_STEPS, description="Step limit of every episode.")
    alpha: float = Field(
        0.5,
        gt=0.0,
        le=1.0,
        description="Learning rate alpha of eq. 2.7: constant, or its first value (see "
        "alpha_schedule).",
    )
    alpha_schedule: AlphaSchedule = Field(
        "visits",
        description="'constant': every update uses alpha. 'visits': the update of Q(s, a) uses "
        "alpha / N(s, a)**alpha_exponent, N counting the times a was chosen in s, so that the "
        "table settles (a constant rate keeps chasing the last few noisy rewards).",
    )
    alpha_exponent: float | None = Field(
        None,
        gt=0.5,
        le=1.0,
        description="omega of the 'visits' schedule: 1 averages every target alike; between 0.5 "
        "and 1 later targets weigh more. null: the default chosen by measurement for each "
        "physics, 1 in the lattice (benchmarks/science.py) and 0.6 in active_brownian "
        "(benchmarks/decision_interval.py).",
    )
    gamma: float = Field(
        0.9,
        ge=0.0,
        le=1.0,
        description="Discount factor gamma of eq. 2.7, once per decision (in active_brownian "
        "once per learning.decision_interval_s; see horizon_s for a discount in seconds).",
    )
    horizon_s: float | None = Field(
        None,
        gt=0.0,
        le=1e9,
        description="active_brownian: the discount as a time, s: a reward t seconds ahead "
        "counts exp(-t / horizon_s), so gamma per decision is exp(-decision_interval_s / "
        "horizon_s) and runs that decide at different intervals look equally far ahead. null: "
        "learning.gamma per decision (0.9 a decision of 1 s: a horizon of about 9.5 s). Given, "
        "learning.gamma is left at its default; the lattice refuses it.",
    )
    epsilon_start: float = Field(
        1.0, ge=0.0, le=1.0, description="Exploration rate of the first episode."
    )
    epsilon_end: float = Field(
        0.05,
        ge=0.0,
        le=1.0,
        description="Floor of the exploration rate; at most epsilon_start.",
    )
    epsilon_decay: float | None = Field(
        None,
        gt=0.0,
        le=1.0,
        description="Per-episode factor: epsilon of episode e is "
        "max(epsilon_end, epsilon_start * epsilon_decay**e). null (the default) picks the "
        "factor that brings epsilon to its floor after 80% of the training episodes; a factor "
        "given here may not reach the floor within them.",
    )
    actions: ActionSet = Field(
        "behaviors",
        description="'behaviors' (the paper's 2.5): follow the gradient, advance toward a sensed "
        "cell, go around the nearest obstacle, explore; the state is the concentration level, "
        "its trend, obstacle proximity and sensed-cell distance. 'directions': a move along one "
        "of 26 lattice directions; the state holds the sign of the sensed gradient on each axis "
        "and obstacle proximity, so the swarm must learn chemotaxis itself.",
    )
    shared_table: bool = Field(
        True,
        description="true: the swarm learns one Q-table together; false: each robot has its own.",
    )
    decision_interval_s: float | None = Field(
        None,
        gt=0.0,
        le=1e6,
        description="active_brownian: the time between two decisions of a robot whose actions "
        "are chosen by number (the Q-learner, or an environment's agent), s; a whole number of "
        "physics.dt_s, at most the episode's time limit. The action holds until the next "
        "decision: steering up the gradient or toward a cell steers again on every step's new "
        "reading, a tumble turns once and then keeps the heading. The reward is summed over the "
        "interval, learning.gamma discounts once per decision, and the Q update is made at "
        "decisions only. Fixed rules decide every step. null: 1 s (chosen by measurement: "
        "benchmarks/decision_interval.py), or the whole episode if it is shorter; physics.dt_s "
        "decides every step. The lattice decides every step and refuses it.",
    )

    @model_validator(mode="after")
    def _epsilon_order(self) -> Learning:
        if self.epsilon_end > self.epsilon_start:
            raise _field_error(
                "Learning", ("epsilon_end",), self.epsilon_end, "must not exceed epsilon_start"
            )
        return self


class Rewards(_Part):
    """The reward function of paper 2.7."""

    reach: float = Field(
        10.0, ge=-1e6, le=1e6, description="Reward for reaching a cell (paper: +10)."
    )
    collision: float = Field(
        -1.0,
        ge=-1e6,
        le=1e6,
        description="Reward for a move blocked by an obstacle (paper: -1). In active_brownian, "
        "per second blocked (dt_s times it a blocked step), so that a path earns the same "
        "whatever dt_s.",
    )
    approach: float = Field(
        1.0,
        ge=-1e6,
        le=1e6,
        description="Reward per length unit closed toward the nearest cell, the biomarker "
        "source (paper: +1 per unit); moving away costs the same.",
    )
    step: float = Field(
        -0.1,
        ge=-1e6,
        le=1e6,
        description="Reward for every step a robot takes (not in the paper): a small cost, so "
        "that a return measures how quickly a cell was reached, not only that it was. In "
        "active_brownian, per second (dt_s times it a step).",
    )


class Evaluation(_Part):
    """How the learned (or fixed) policy is judged after training: greedily, in fresh worlds."""

    worlds: int = Field(
        20,
        ge=1,
        le=1000,
        description="Evaluation episodes, each in a fresh world drawn from a stream of its own, "
        "so that every policy run with the same seed is judged in the same worlds. The summary "
        "is the mean over them; the first is recorded for the trajectory and the pictures.",
    )


LARGEST_AUTOMATIC_DT_S = 0.01
DT_FLOOR_S = 1e-9  # the finest time step: within the bounds no motion needs a finer one


def _time_step_bounds(
    d_t: float, d_r: float, speed: float, radius: float, dt: float
) -> list[tuple[float, float, float, str]]:
    """Each bound a time step must keep: (its value at dt, the largest allowed, the dt that
    reaches it, what breaking it means)."""
    half = radius / 2
    return [
        (d_r * dt, 0.05, 0.05 / d_r if d_r else math.inf,
         "the heading would turn by D_R dt = {value:.3g} per step (at most 0.05)"),
        (speed * dt, half, half / speed if speed else math.inf,
         "a step would swim {value:.3g} µm, over half of robot_radius_um"),
        (math.sqrt(2 * d_t * dt), half, half**2 / (2 * d_t) if d_t else math.inf,
         "a step would jiggle sqrt(2 D_T dt) = {value:.3g} µm, over half of robot_radius_um"),
    ]  # fmt: skip


def automatic_dt_s(d_t: float, d_r: float, speed: float, radius: float) -> float:
    """The time step that validation fills in: the largest that keeps every bound, at most
    0.01 s, two significant figures rounded down."""
    fine = min(b[2] for b in _time_step_bounds(d_t, d_r, speed, radius, 0.0))
    return min(LARGEST_AUTOMATIC_DT_S, float(_round_down(fine)))


def time_limit_steps(time_limit_s: float, dt_s: float) -> int:
    """learning.max_steps of a time limit: ceil(time_limit_s / dt_s), and at least one step."""
    return max(1, math.ceil(time_limit_s / dt_s - 1e-9))


# The bounds a field's metadata may hold (annotated_types' Gt, Ge, Lt and Le), by attribute.
_BOUNDS = (("gt", operator.gt), ("ge", operator.ge), ("lt", operator.lt), ("le", operator.le))


def _admits(model: type[BaseModel], name: str, value: Any) -> bool:
    """Whether ``value`` is a number that the field ``name`` of ``model`` takes: finite and
    within its bounds, so that what is derived from it is too."""
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        return False
    return all(
        holds(value, getattr(bound, kind))
        for bound in model.model_fields[name].metadata
        for kind, holds in _BOUNDS
        if getattr(bound, kind, None) is not None
    )


def fill_physics(data: Any) -> Any:
    """An active Brownian physics section with what it leaves out filled in: D_T and D_R from
    Stokes-Einstein(-Debye), dt_s the largest step that keeps every bound (``automatic_dt_s``).
    Only what is derived from values within their fields' bounds is filled in (the bounds keep
    it finite and within its own); anything else is returned as it came, for validation to
    refuse. Never raises."""
    if not isinstance(data, dict) or data.get("model") != "active_brownian":
        return data
    fields = Physics.model_fields
    stokes = ("temperature_k", "viscosity_mpa_s", "robot_radius_um", "swim_speed_um_s")
    got = {k: data.get(k, fields[k].default) for k in stokes}
    if not all(_admits(Physics, k, got[k]) for k in stokes):
        return data  # the fields' own validation says what is wrong
    t, eta, r, v = (float(got[k]) for k in stokes)
    filled = dict(data)
    if filled.get("diffusion_um2_s") is None:
        filled["diffusion_um2_s"] = stokes_einstein_um2_s(t, eta, r)
    if filled.get("rotational_diffusion_s") is None:
        filled["rotational_diffusion_s"] = stokes_einstein_debye_s(t, eta, r)
    d_t, d_r = filled["diffusion_um2_s"], filled["rotational_diffusion_s"]
    if (
        filled.get("dt_s") is None
        and _admits(Physics, "diffusion_um2_s", d_t)
        and _admits(Physics, "rotational_diffusion_s", d_r)
    ):
        filled["dt_s"] = automatic_dt_s(float(d_t), float(d_r), v, r)
    d_m = data.get("molecule_diffusion_um2_s", fields["molecule_diffusion_um2_s"].default)
    if (
        filled.get("sensor", fields["sensor"].default) == "counted"
        and filled.get("integration_time_s") is None
        and _admits(Physics, "molecule_diffusion_um2_s", d_m)
    ):
        filled["integration_time_s"] = max(DEFAULT_INTEGRATION_TIME_S, crossing_time_s(r, d_m))
    return filled


def crossing_time_s(radius_um: float, molecule_diffusion_um2_s: float) -> float:
    """r^2 / D_m: the time a molecule takes to diffuse across a body of radius r, s; two counts
    closer in time than it count many of the same molecules (Berg & Purcell 1977)."""
    return radius_um**2 / molecule_diffusion_um2_s


def _round_down(value: float) -> str:
    """A time step to suggest: two significant figures, rounded down so that it keeps the bound."""
    if not math.isfinite(value) or value <= 0:
        return f"{value:g}"
    scale = 10 ** (math.floor(math.log10(value)) - 1)
    return f"{math.floor(value / scale) * scale:.3g}"


class Physics(_Part):
    """How robots, cells and molecules move. 'lattice' (the paper's, the default): a robot moves
    exactly robots.speed along the direction its policy chooses, every step. 'active_brownian':
    a sphere of robot_radius_um swims at swim_speed_um_s along a heading that diffuses, jiggles
    with translational diffusion, and can only steer (at most max_turn_rate_rad_s); the field is
    the steady state of what each cell secretes, read at the Berg-Purcell limit. Every quantity
    below belongs to 'active_brownian' (and is refused with 'lattice'); the documentation's
    physics page (docs/explanation/physics.md) gives each default's source. The bounds are
    physical, and hold what is derived from them (D_T, D_R, dt_s, the step limit) finite and
    within its own: each says why in its description."""

    model: PhysicsModel = Field(
        "lattice",
        description="'lattice' (the paper's model, in simulation units and steps) or "
        "'active_brownian' (SI: µm, s, nM; every length of the scenario is then in µm).",
    )
    dt_s: float | None = Field(
        None,
        ge=DT_FLOOR_S,
        le=10.0,
        description="Time step, s. It must resolve the motion: the heading may turn by "
        "D_R dt <= 0.05 per step, and a step (swimming or jiggling) may cover at most half of "
        "robot_radius_um; a coarser step is refused with the dt_s that would do. null: the "
        "largest such step, at most 0.01 s, filled in in the resolved scenario (so a study "
        "over robot_radius_um gets a fitting step at every radius). At least 1e-9 s: within "
        "the other fields' bounds no motion needs a finer step (the finest, 1.2e-9 s, is for "
        "a 10 nm robot whose D_T is 1e4 µm²/s).",
    )
    time_limit_s: float | None = Field(
        None,
        ge=DT_FLOOR_S,
        le=1e6,
        description="The episode's time limit, s: learning.max_steps becomes ceil(time_limit_s "
        "/ dt_s) (at least 1, at most 1,000,000: a longer limit is refused), filled in. null: "
        "learning.max_steps steps of dt_s. At least 1e-9 s, dt_s's floor.",
    )
    temperature_k: float = Field(
        310.15, ge=250.0, le=400.0, description="Temperature, K (37 degrees C: the body's)."
    )
    viscosity_mpa_s: float = Field(
        0.69,
        ge=0.01,
        le=1e5,
        description="Viscosity of the fluid, mPa s (water at 37 degrees C: 0.69; interstitial "
        "fluid is close to water, a mucus or matrix far more). From 0.01, a gas's (air: "
        "0.018), to 1e5 (100 Pa s, a thick mucus).",
    )
    robot_radius_um: float = Field(
        1.0,
        ge=0.01,
        le=50.0,
        description="Radius of a (spherical) robot, µm: from 10 nm, a small nanoparticle, to "
        "50 µm.",
    )
    swim_speed_um_s: float = Field(
        10.0,
        ge=0.0,
        le=1000.0,
        description="Self-propulsion speed along the heading, µm/s (0: a passive Brownian "
        "particle).",
    )
    max_turn_rate_rad_s: float = Field(
        10.0,
        ge=0.0,
        le=1e4,
        description="The fastest a robot can steer its heading, rad/s; a tumble is a random new "
        "heading and not bound by it.",
    )
    diffusion_um2_s: float | None = Field(
        None,
        ge=0.0,
        le=1e4,
        description="Translational diffusion D_T, µm²/s. null: Stokes-Einstein, "
        "k_B T / (6 pi eta R), filled in in the resolved scenario. At most 1e4, above any "
        "Stokes-Einstein value the other bounds allow (2,930: 10 nm, 0.01 mPa s, 400 K).",
    )
    rotational_diffusion_s: float | None = Field(
        None,
        ge=0.0,
        le=2.5e7,
        description="Rotational diffusion D_R, 1/s: the heading correlation decays as "
        "exp(-2 D_R t). null: Stokes-Einstein-Debye, k_B T / (8 pi eta R^3), filled in in the "
        "resolved scenario. At most 2.5e7, above any Stokes-Einstein-Debye value the other "
        "bounds allow (2.2e7: 10 nm, 0.01 mPa s, 400 K) and resolved by a step of 2e-9 s.",
    )
    cell_radius_um: float = Field(
        7.5,
        ge=0.5,
        le=100.0,
        description="Radius of a cancer cell, µm; a robot reaches a cell when its surface "
        "touches the cell's. At least 0.5 µm, a bacterium's: no cell is smaller.",
    )
    cell_diffusion_um2_s: float = Field(
        0.005,
        ge=0.0,
        le=100.0,
        description="Cells move as a random walk with this diffusion coefficient, µm²/s "
        "(0.005: about 1.3 µm a minute).",
    )
    secretion_molecules_s: float = Field(
        100.0,
        ge=1.0,
        le=1e9,
        description="Biomarker molecules a cell secretes per second, at least one (a cell "
        "secretes a cytokine at tens to thousands a second).",
    )
    molecule_diffusion_um2_s: float = Field(
        100.0,
        ge=0.01,
        le=1e4,
        description="Diffusion coefficient of the biomarker molecule, µm²/s (about 100 for a "
        "small protein, 60 for an antibody). At least 0.01, a 30 µm bead's in water: every "
        "molecule diffuses faster.",
    )
    decay_rate_s: float = Field(
        0.01,
        ge=1e-6,
        le=1e3,
        description="Rate at which the biomarker is cleared or decays, 1/s. The field of a cell "
        "is Q exp(-r/lambda) / (4 pi D_m r) with lambda = sqrt(D_m / decay_rate_s). At least "
        "1e-6, a lifetime of 1e6 s (the longest time_limit_s): slower is no decay in a run.",
    )
    tumble_rate_s: float = Field(
        1.0,
        ge=0.0,
        le=1e4,
        description="run_and_tumble and steer_and_tumble: tumbles per second while the reading "
        "does not rise; blind_tumble: tumbles per second, always.",
    )
    tumble_rate_rising_s: float = Field(
        0.25,
        ge=0.0,
        le=1e4,
        description="run_and_tumble and steer_and_tumble: tumbles per second while the reading "
        "rises (fewer: runs up "
        "the gradient last longer).",
    )
    memory_s: float = Field(
        1.0,
        ge=0.0,
        le=1e4,
        description="Temporal sensing: a reading is compared with the mean of the robot's "
        "readings over this past time to tell whether it rises (0: with the last reading).",
    )
    short_memory_s: float = Field(
        0.0,
        ge=0.0,
        le=1e4,
        description="Temporal sensing on two time scales: what is compared with the mean over "
        "memory_s is the mean of the robot's readings over this shorter past time (an "
        "exponential average, as memory_s's), so that a rise is told from a few noisy counts "
        "rather than one; the rules that tumble and the Q-learner's 'rising' use it. Less than "
        "memory_s. 0: the reading itself.",
    )
    sensor: Sensor = Field(
        "counted",
        description="How a robot reads the biomarker. 'counted': molecules counted, Poisson, "
        "by six receptor patches (each a sixth of the surface, facing the axes' two ways) over "
        "integration_time_s; the reading is their sum, the gradient their differences, both "
        "held until the next count (so a reading is 0 where molecules are scarce, and what a "
        "robot learns of the field does not grow as dt_s shrinks). 'each_step', the default "
        "before molecules were counted: every step a reading of the whole body over dt_s at "
        "the Berg-Purcell limit (a gamma draw of mean the concentration, never 0) and, for "
        "the gradient, one such reading at each end of each axis; what it finds moves with "
        "dt_s.",
    )
    integration_time_s: float | None = Field(
        None,
        ge=1e-6,
        le=100.0,
        description="sensor 'counted': the time over which a count is taken, s, a whole "
        "number of steps of dt_s (rounded to the nearest). At least r^2 / D_m, the time a "
        "molecule takes to cross the body (Berg & Purcell 1977: counts closer in time are not "
        "independent), and at least dt_s. null: 0.1 s (Alonso & Kirkegaard 2024's receptors "
        "count over 0.1 s) or r^2 / D_m if that is longer, filled in in the resolved scenario.",
    )
    receptors: int | None = Field(
        None,
        ge=1,
        le=10**9,
        description="sensor 'counted': the receptors on the body's surface, each a disc of "
        "receptor_radius_nm. The body takes in N s / (N s + pi a) of a perfect absorber's "
        "4 pi D_m a c molecules a second (Berg & Purcell 1977), and the gradient's share of "
        "them as a uniformly absorbing surface of that rate would (docs/explanation/"
        "sensing.md). They must fit on the surface (N s^2 <= 4 a^2). null: a perfectly "
        "absorbing body, the limit of many receptors, the most any body of its size can count.",
    )
    receptor_radius_nm: float = Field(
        1.0,
        ge=0.01,
        le=1000.0,
        description="sensor 'counted', with receptors: a receptor's radius, nm (Berg & Purcell "
        "1977 take about 1 nm for a bacterium's).",
    )
    gradient_memory_s: float = Field(
        0.0,
        ge=0.0,
        le=1e4,
        description="sensor 'counted': the gradient a robot steers by is the exponential "
        "average of its counts' gradients over this past time, s (each count weighs "
        "integration_time_s / gradient_memory_s, at most 1), so that a rule steers by what "
        "several counts agree on rather than by each count's noise; the reading's own memory "
        "is memory_s. 0: the last count's gradient alone.",
    )

    @property
    def step_s(self) -> float:
        """dt_s, which validation fills in for active Brownian motion (0 for the lattice)."""
        return self.dt_s or 0.0

    @model_validator(mode="before")
    @classmethod
    def _stokes(cls, data: Any) -> Any:
        """D_T and D_R default to Stokes-Einstein(-Debye), and dt_s to the largest step that
        resolves the motion, filled in so the resolved scenario shows what ran."""
        return fill_physics(data)

    @model_validator(mode="after")
    def _resolves_the_motion(self) -> Physics:
        if self.model != "active_brownian":
            fields = type(self).model_fields
            changed = [k for k in fields if k != "model" and getattr(self, k) != fields[k].default]
            if changed:
                raise _field_error(
                    "Physics", (changed[0],), getattr(self, changed[0]),
                    "belongs to physics.model 'active_brownian'; the lattice physics has no use "
                    "for it",
                )  # fmt: skip
            return self
        dt = self.dt_s or 0.0
        bounds = _time_step_bounds(
            self.diffusion_um2_s or 0.0, self.rotational_diffusion_s or 0.0,
            self.swim_speed_um_s, self.robot_radius_um, dt,
        )  # fmt: skip
        fine = min(b[2] for b in bounds)  # a dt that keeps every bound
        for value, largest, _, message in bounds:
            if value > largest * (1 + 1e-12):
                raise _field_error(
                    "Physics", ("dt_s",), self.dt_s,
                    f"dt_s {dt:g} s is too coarse: " + message.format(value=value)
                    + f"; dt_s <= {_round_down(fine)} s would do",
                )  # fmt: skip
        self._sensing_fits(dt)
        return self._time_limit_fits()

    def _sensing_fits(self, dt: float) -> None:
        """The short memory is shorter than the long; integration_time_s and gradient_memory_s
        belong to sensor 'counted', and the integration time is at least the time a molecule
        takes to cross the body and a step."""
        if self.short_memory_s and self.short_memory_s >= self.memory_s:
            raise _field_error(
                "Physics", ("short_memory_s",), self.short_memory_s,
                f"must be shorter than memory_s ({self.memory_s:g} s), the mean it is compared "
                "with",
            )  # fmt: skip
        if self.gradient_memory_s and self.sensor != "counted":
            raise _field_error(
                "Physics", ("gradient_memory_s",), self.gradient_memory_s,
                "belongs to sensor 'counted' (sensor 'each_step' reads the gradient anew each "
                "step)",
            )  # fmt: skip
        if self.receptors is not None or self.receptor_radius_nm != 1.0:
            self._receptors_fit()
        tau = self.integration_time_s
        if tau is None:
            return
        crossing = crossing_time_s(self.robot_radius_um, self.molecule_diffusion_um2_s)
        if self.sensor != "counted":
            problem = "belongs to sensor 'counted' (sensor 'each_step' reads over each step)"
        elif tau < crossing * (1 - 1e-12):
            problem = (
                f"{tau:g} s is shorter than r^2 / D_m = {crossing:.3g} s, the time a molecule "
                "takes to cross the body: counts closer in time are not independent; "
                f"integration_time_s >= {crossing:.3g} s would do"
            )
        elif tau < dt * (1 - 1e-12):
            problem = f"{tau:g} s is shorter than a step (dt_s {dt:g} s): a count takes whole steps"
        else:
            return
        raise _field_error("Physics", ("integration_time_s",), tau, problem)

    def _receptors_fit(self) -> None:
        """Receptors belong to sensor 'counted' (and their radius to receptors), and fit on the
        body: their discs cover at most its surface."""
        field = "receptors" if self.receptors is not None else "receptor_radius_nm"
        value = self.receptors if self.receptors is not None else self.receptor_radius_nm
        if self.sensor != "counted":
            problem = "belongs to sensor 'counted' (sensor 'each_step' reads a fixed share)"
        elif self.receptors is None:
            problem = "belongs to receptors (null: a perfect absorber, whose receptors are all)"
        else:
            s_um, a = self.receptor_radius_nm * 1e-3, self.robot_radius_um
            if self.receptors * s_um * s_um <= 4.0 * a * a:
                return
            most = math.floor(4.0 * a * a / (s_um * s_um))
            problem = (
                f"{self.receptors} receptors of {self.receptor_radius_nm:g} nm do not fit on a "
                f"body of {a:g} um: at most {most} (N s^2 <= 4 a^2)"
            )
        raise _field_error("Physics", (field,), value, problem)

    def _time_limit_fits(self) -> Physics:
        """A time limit is at most as many steps of dt_s as learning.max_steps takes: refused
        at dt_s when it was given (it is not the one filled in), else at time_limit_s."""
        limit, dt = self.time_limit_s, self.step_s
        if limit is None or not dt:
            return self
        steps = time_limit_steps(limit, dt)
        if steps <= MAX_STEPS:
            return self
        filled = automatic_dt_s(
            self.diffusion_um2_s or 0.0, self.rotational_diffusion_s or 0.0,
            self.swim_speed_um_s, self.robot_radius_um,
        )  # fmt: skip
        if dt != filled:
            raise _field_error(
                "Physics", ("dt_s",), dt,
                f"dt_s {dt:g} s makes time_limit_s {limit:g} s {steps:,} steps, more than the "
                f"{MAX_STEPS:,} learning.max_steps takes: a longer dt_s or a shorter "
                "time_limit_s would do",
            )  # fmt: skip
        raise _field_error(
            "Physics", ("time_limit_s",), limit,
            f"{limit:g} s is {steps:,} steps of dt_s {dt:g} s (the largest that resolves the "
            f"motion), more than the {MAX_STEPS:,} learning.max_steps takes: time_limit_s <= "
            f"{_round_down(MAX_STEPS * dt)} s would do",
        )  # fmt: skip


class Communication(_Part):
    """How robots signal to each other. 'none' (the paper's): they share nothing but, in
    training, the Q-table. 'attractant': a robot bound to a cell (it delivered its payload)
    releases an attractant that diffuses and decays with rates of its own, solved on a grid
    (explicit finite differences: the cost grows with the grid, not with senders x readers);
    others read it as they read the biomarker, with the same noise rules (chemical stigmergy,
    Harasha & Lynch, arXiv 2509.06893; signalling nanoparticles, von Maltzahn et al., Nat.
    Mater. 10, 545 (2011)). 'attractant_repellent': as 'attractant' while the cell still needs
    drug, and a repellent (same rates) once it is treated, so later robots go elsewhere.
    'broadcast': an engineered radio, not a molecule: a robot that reaches a cell sends its
    position to every robot within range, who holds the nearest message until it gets there.
    The lattice physics takes diffusion, decay_rate and release_rate (length units and steps);
    active_brownian takes diffusion_um2_s, decay_rate_s and release_molecules_s."""

    model: CommunicationModel = Field(
        "none", description="'none', 'attractant', 'attractant_repellent' or 'broadcast'."
    )
    diffusion: float = Field(
        0.5,
        ge=1e-6,
        le=100.0,
        description="Lattice: the signal's diffusion coefficient, length units^2 per step. At "
        "least 1e-6: a slower signal spreads under 2.5 units in the longest episode.",
    )
    decay_rate: float = Field(
        0.01,
        ge=0.0,
        le=1.0,
        description="Lattice: the share of the signal that decays per step.",
    )
    release_rate: float = Field(
        1.0,
        gt=0.0,
        le=1e6,
        description="Lattice: what one bound robot releases per step, concentration x length^3.",
    )
    diffusion_um2_s: float = Field(
        100.0,
        ge=0.01,
        le=1e4,
        description="Active Brownian: the signal's diffusion coefficient, µm²/s (a small "
        "protein in tissue: about 100). At least 0.01, a 30 µm bead's in water: every molecule "
        "diffuses faster.",
    )
    decay_rate_s: float = Field(
        0.1, ge=0.0, le=1e3, description="Active Brownian: the signal's decay rate, 1/s."
    )
    release_molecules_s: float = Field(
        1e4,
        ge=1.0,
        le=1e9,
        description="Active Brownian: molecules one bound robot releases per second, at least one.",
    )
    threshold: float = Field(
        1e-3,
        ge=0.0,
        le=1e6,
        description="A signal reading above this is received (the state's 'signal'), in the "
        "biomarker's concentration units (nM in active_brownian); never below "
        "biomarker.detection_threshold, which holds for the signal as for the biomarker.",
    )
    range: float = Field(
        15.0,
        gt=0.0,
        le=10_000.0,
        description="Broadcast: how far a message carries, length units (µm in active_brownian).",
    )
    nodes_per_axis: int = Field(
        33,
        ge=5,
        le=129,
        description="Grid nodes per axis on which the signal is solved (spanning the cube); "
        "the solver's step is the largest stable one, a whole number of the engine's steps.",
    )


class Scenario(_Part):
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
        return _steering_by_default(data)

    @model_validator(mode="after")
    def _one_physics(self) -> Scenario:
        """Each physics takes its own policies and action set, and a field that only the other
        has a use for is refused rather than ignored."""
        brownian = self.physics.model == "active_brownian"
        allowed = BROWNIAN_POLICIES if brownian else LATTICE_POLICIES
        if self.robots.policy not in allowed:
            raise _field_error(
                "Scenario", ("robots", "policy"), self.robots.policy,
                f"is not a policy of physics.model '{self.physics.model}', which takes "
                + ", ".join(sorted(allowed)),
            )  # fmt: skip
        if (self.learning.actions == "steering") != brownian:
            wanted = "steering" if brownian else "behaviors or directions"
            raise _field_error(
                "Scenario", ("learning", "actions"), self.learning.actions,
                f"physics.model '{self.physics.model}' takes the action set {wanted}",
            )  # fmt: skip
        if brownian and self.physics.time_limit_s is not None and self.physics.dt_s:
            steps = time_limit_steps(self.physics.time_limit_s, self.physics.dt_s)
            if self.learning.max_steps != steps:
                raise _field_error(
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
                    raise _field_error(
                        "Scenario", (part, name), getattr(section, name),
                        f"has no use in physics.model 'active_brownian': {instead}",
                    )  # fmt: skip
            if self.reach_distance != type(self).model_fields["reach_distance"].default:
                raise _field_error(
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
            raise _field_error(
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
            raise _field_error(
                "Scenario", where, interval,
                f"is shorter than one step (physics.dt_s {dt:g} s): a robot decides at most "
                "once a step",
            )  # fmt: skip
        if abs(steps - whole) > 1e-9 * max(1.0, steps):
            below, above = math.floor(steps) * dt, math.ceil(steps) * dt
            raise _field_error(
                "Scenario", where, interval,
                f"is not a whole number of steps of physics.dt_s {dt:g} s: {below:.6g} or "
                f"{above:.6g} would do",
            )  # fmt: skip
        if whole > self.learning.max_steps:
            raise _field_error(
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
            raise _field_error(
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
                raise _field_error(
                    "Scenario", ("communication", name), getattr(comm, name),
                    f"has no use in physics.model '{self.physics.model}', which takes "
                    + ", ".join(instead),
                )  # fmt: skip
        if (
            comm.model != "none"
            and self.robots.policy == "q_learning"
            and self.learning.actions == "directions"
        ):
            raise _field_error(
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
            raise _field_error(
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
            raise _field_error(
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
            raise _field_error(
                "Scenario", ("robots", "policy"), self.robots.policy,
                "policy_from needs q_learning: only a learned policy can be evaluated",
            )  # fmt: skip
        if self.learning.episodes != 0:
            raise _field_error(
                "Scenario", ("learning", "episodes"), self.learning.episodes,
                "must be 0 with policy_from: a learned policy is evaluated, not trained further",
            )  # fmt: skip
        return self

    @model_validator(mode="after")
    def _fits_in_space(self) -> Scenario:
        half = self.space.size / 2
        radius = self.obstacles.radius
        if radius >= half / 2:
            raise _field_error(
                "Scenario", ("obstacles", "radius"), radius,
                "must be less than a quarter of space.size",
            )  # fmt: skip
        sphere = 4.0 / 3.0 * math.pi * radius**3
        if self.obstacles.count * sphere > MAX_OBSTACLE_VOLUME_FRACTION * self.space.size**3:
            raise _field_error(
                "Scenario", ("obstacles", "count"), self.obstacles.count,
                f"obstacles of this radius would fill more than "
                f"{MAX_OBSTACLE_VOLUME_FRACTION:.0%} of the space",
            )  # fmt: skip
        if self.reach_distance >= half:
            raise _field_error(
                "Scenario", ("reach_distance",), self.reach_distance,
                "must be less than half of space.size",
            )  # fmt: skip
        return self

    def _swarm_robot_step(self) -> float:
        """What exclusion and signalling add to one active robot's step, in work units."""
        units = WORK_EXCLUSION if self.robots.exclusion else 0.0
        model = self.communication.model
        if model == "broadcast":
            units += WORK_RELIST
        elif model != "none":
            species = 2 if model == "attractant_repellent" else 1
            units += WORK_SIGNAL_READ * species
        return units

    def _swarm_step(self) -> float:
        """What the signal's grid adds to one step, in work units: its nodes at every solver
        step, and a release by every robot (bound or not, each is looked at) at every update."""
        model = self.communication.model
        if model in ("none", "broadcast"):
            return 0.0
        every, substeps = self.signal_solver_steps
        species = 2 if model == "attractant_repellent" else 1
        grid = WORK_NODE * self.communication.nodes_per_axis**3 * species * substeps
        return (grid + WORK_RELEASE * self.robots.count) / every

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
        + evaluation worlds)."""
        return self.robots.count * self.learning.max_steps * self.episodes

    @property
    def episodes(self) -> int:
        """Episodes a run has in all: training, then evaluation."""
        return self.learning.episodes + self.evaluation.worlds

    @property
    def sources(self) -> int:
        """Point sources of the field: the cells, or their emitters for the inverse-square model."""
        if self.biomarker.model in ("inverse_square", "sampled_gaussian"):
            return self.cells.count * self.biomarker.emitters_per_cell
        return self.cells.count

    @property
    def robot_step_overhead(self) -> float:
        """C, the work of one robot's step besides its scans and field terms: Q-learning's
        behaviours cost most, the baselines least."""
        if self.robots.policy == "q_learning":
            return WORK_ROBOT_STEP[self.learning.actions]
        return WORK_ROBOT_STEP["baseline"]

    @property
    def work(self) -> int:
        """The most this scenario can cost, in work units (about a nanosecond of one core each,
        see the ``WORK_*`` weights): every robot active for every step of every episode.

        Unlike ``robot_steps_budget`` it weighs a robot-step by what it does: a field term per
        source, two scans of the obstacles and of the cells; and it adds what a step, an
        episode and the recorded evaluation cost besides (``work_for``)."""
        episodes = self.episodes
        steps = self.learning.max_steps * episodes
        evaluation_steps = self.learning.max_steps * self.evaluation.worlds
        return self.work_for(self.robots.count * steps, steps, episodes, evaluation_steps)

    def work_for(self, robot_steps: int, steps: int, episodes: int, evaluation_steps: int) -> int:
        """The work of a run of this scenario that took ``robot_steps`` robot-steps over
        ``steps`` steps of ``episodes`` episodes, ``evaluation_steps`` of them in the evaluation
        (where the field is also measured at every robot for the metrics)."""
        n = self.robots.count
        c = self.cells.count
        o = self.obstacles.count
        k = self.sources
        source = WORK_SOURCE[self.biomarker.model]
        # units per active robot and step: sense (k terms), nearest obstacle and the collision
        # test (o tests each), nearest cell before and after the move (c tests each)
        robot_step = self.robot_step_overhead + source * k + 2 * WORK_PAIR * (o + c)
        # units per step: place the sources; a cell moves unless into one of o obstacles; an
        # obstacle moves unless onto one of n robots or c cells
        step = WORK_STEP + WORK_PLACE * k
        if self.cells.motion_std > 0:
            step += c * (WORK_DRAW + WORK_PAIR * o)
        if self.obstacles.motion_std > 0:
            step += o * (WORK_DRAW + WORK_PAIR * (n + c))
        # units per episode: draw the world (robots clear of cells, obstacles clear of both, at
        # one attempt each; emitter offsets for every model), and close it with one more step of
        # every robot
        emitters = c * self.biomarker.emitters_per_cell
        episode = (
            WORK_DRAW * (c + 2 * n + o + emitters)
            + WORK_PAIR * (n * c + o * (n + c))
            + n * robot_step
        )
        robot_step += self._swarm_robot_step()
        step += self._swarm_step()
        # a broadcast reaches the robots in the 27 cells of the radio's list around its sender:
        # at most every robot delivers once an episode, each message scanning that share
        if self.communication.model == "broadcast":
            share = min(1.0, (3 * self.communication.range / self.space.size) ** 3)
            episode += WORK_PAIR * n * n * share
        # units per evaluation step: the field and the nearest cell measured at every robot
        evaluation_step = n * (source * k + WORK_PAIR * c)
        total = (
            robot_steps * robot_step
            + steps * step
            + episodes * episode
            + evaluation_steps * evaluation_step
        )
        return math.ceil(total)


# The paper's worlds (its text and figures), the world of the authors' published script, and
# worlds where sensing is honest: a noise floor, a detection threshold, cells sensed only up
# close, and more obstacles that drift.
HARD: dict[str, Any] = {
    "biomarker": {"noise_floor": 0.01, "detection_threshold": 0.005},
    "robots": {"cell_sensing_radius": 2.0},
    "obstacles": {"count": 30, "motion_std": 0.05},
}
PRESETS: dict[str, dict[str, Any]] = {
    "paper-single": {
        "cells": {"count": 1, "motion_std": 0.2},
        "robots": {"count": 1},
        "obstacles": {"count": 10},
    },
    "paper-swarm": {
        "cells": {"count": 2, "motion_std": 0.2},
        "robots": {"count": 15},
        "obstacles": {"count": 10},
    },
    "authors-script": {
        "space": {"size": 100.0, "walls": False},
        "cells": {"count": 1, "motion_std": 0.2, "start_extent": 1.0},
        "biomarker": {
            "model": "sampled_gaussian",
            "spread": 40.0 / math.sqrt(2.0),
            "emitters_per_cell": 50,
            "emitter_scatter": 5.0,
        },
        "robots": {"count": 1, "start": "corner"},
        "obstacles": {"count": 0},
        "learning": {"max_steps": 1000},
        "reach_distance": 0.5,
    },
    "hard-single": {
        "cells": {"count": 1, "motion_std": 0.2},
        "robots": {"count": 1, **HARD["robots"]},
        "biomarker": HARD["biomarker"],
        "obstacles": HARD["obstacles"],
    },
    "hard-swarm": {
        "cells": {"count": 2, "motion_std": 0.2},
        "robots": {"count": 15, **HARD["robots"]},
        "biomarker": HARD["biomarker"],
        "obstacles": HARD["obstacles"],
    },
}


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
    if _admits(Physics, "time_limit_s", limit) and _admits(Physics, "dt_s", dt):
        steps = time_limit_steps(limit, dt)
        # more than learning takes: left out, for Physics to name time_limit_s or dt_s; both
        # given and at odds: kept, for _one_physics to say so
        if _admits(Learning, "max_steps", steps):
            learning = {"max_steps": steps, **learning}
    return {**data, "physics": physics, "learning": learning}


def deep_merge(base: dict[str, Any], override: dict[str, Any]) -> dict[str, Any]:
    """``base`` with ``override`` laid over it, section by section (a preset under a request)."""
    merged = dict(base)
    for key, value in override.items():
        if isinstance(value, dict) and isinstance(merged.get(key), dict):
            merged[key] = deep_merge(merged[key], value)
        else:
            merged[key] = value
    return merged


# The worlds of the physical question (active Brownian, µm and s): see
# docs/explanation/learning.md.
TUMOUR: dict[str, Any] = {
    "physics": {"model": "active_brownian", "time_limit_s": 60.0},
    "space": {"size": 150.0},
    "cells": {"count": 1},
    "obstacles": {"count": 40, "radius": 5.0},
    "robots": {"count": 20, "cell_sensing_radius": 0.0, "exclusion": True},
}
# The swarm's world (lattice units and steps): see docs/explanation/swarm.md.
DIFFUSE_TUMOUR: dict[str, Any] = {
    "space": {"size": 100.0},
    "cells": {"count": 20, "motion_std": 0.05, "start_extent": 0.9, "capacity": 3},
    "biomarker": {"spread": 3.0, "noise_floor": 0.005, "detection_threshold": 0.01},
    "obstacles": {"count": 20, "motion_std": 0.05},
    "robots": {"count": 100, "policy": "rule", "exclusion": True, "cell_sensing_radius": 2.0},
    "learning": {"max_steps": 1000},
    # what a bound robot releases when robots signal (chosen on seeds 1000+, never reported)
    "communication": {"release_rate": 10.0},
}
PRESETS["diffuse-tumour"] = DIFFUSE_TUMOUR
# Alonso & Kirkegaard, PNAS Nexus 3, pgae235 (2024), as their code sets it (kirkegaardlab/chemoxrl,
# models/*/env_params.json): a swimmer of radius 0.5-3.4 um at 5 um/s, D_R 0.025 1/s and no
# translational noise, a decision and a count every 0.1 s, a turn of up to pi per decision, a
# field e^(-r/lambda) with lambda = sqrt(D / k) = sqrt(100 / 0.01) = 100 um, a source of
# N = 1e4-1e5, an episode of 256 decisions, a start 36-69 um away and success within
# -ln(0.9) lambda = 10.5 um. Their world is two-dimensional and their five receptors each count
# N / 2 pi times their area times the field; here the field is a 3-D source's and the body a
# perfect absorber's six patches (4 pi D a c a second in all), so the secretion is chosen to count
# as many molecules as their N = 1e4 does (13 in 0.1 s at 50 um, for a 0.5 um robot):
# Q = 21,500 molecules/s (86,000 while a body counted pi D a c, a quarter of an absorber's).
ALONSO_KIRKEGAARD: dict[str, Any] = {
    "physics": {
        "model": "active_brownian", "robot_radius_um": 0.5, "swim_speed_um_s": 5.0,
        "rotational_diffusion_s": 0.025, "diffusion_um2_s": 0.0, "sensor": "counted",
        "max_turn_rate_rad_s": 31.4, "molecule_diffusion_um2_s": 100.0,
        "decay_rate_s": 0.01, "secretion_molecules_s": 21_500.0, "cell_radius_um": 10.0,
        "cell_diffusion_um2_s": 0.0, "time_limit_s": 25.6,
    },
    # the cell starts within 3 um of the centre, the robot anywhere else: 55 um away on average
    "space": {"size": 120.0, "walls": False},
    "cells": {"count": 1, "start_extent": 0.05},
    "obstacles": {"count": 0},
    "robots": {"count": 1, "cell_sensing_radius": 0.0},
    "learning": {"decision_interval_s": 0.1},
}  # fmt: skip
PRESETS["alonso-kirkegaard"] = ALONSO_KIRKEGAARD
PRESETS.update(
    {
        "tumour-microswimmers": TUMOUR,
        "tumour-nanorobots": deep_merge(TUMOUR, {"physics": {"robot_radius_um": 0.2}}),
        "tumour-passive": deep_merge(
            TUMOUR, {"physics": {"swim_speed_um_s": 0.0}, "robots": {"policy": "uncontrolled"}}
        ),
        # signalling in the tissue: robots bound to a cell call the others with an attractant
        "tumour-signals": deep_merge(
            TUMOUR,
            {
                "cells": {"count": 5, "capacity": 3},
                "robots": {"count": 40, "policy": "gradient"},
                "communication": {"model": "attractant"},
            },
        ),
    }
)


def preset_scenario(name: str, **overrides: Any) -> Scenario:
    """A preset's scenario, with ``overrides`` applied on top (keys as in the JSON schema)."""
    return Scenario.model_validate({"preset": name, **overrides})
