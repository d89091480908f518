"""The parts of a scenario that hold no physics of their own: the space, the cells, the
biomarker field, the obstacles, the robots, the learning, the rewards, the evaluation and the
communication."""

from __future__ import annotations

from pydantic import (
    Field,
    model_validator,
)

from nanonav.scenario.base import Part, field_error
from nanonav.scenario.choices import (
    ActionSet,
    AlphaSchedule,
    CommunicationModel,
    FieldModel,
    Policy,
    RobotStart,
    Schedule,
)
from nanonav.scenario.limits import MAX_STEPS, MAX_TRAINING_DECISIONS


class Space(Part):
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


class Cells(Part):
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


class Biomarker(Part):
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


class Obstacles(Part):
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


class Robots(Part):
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
        "gradient (an upper bound no robot has). In either physics, 'ppo' (a network of 64x64) "
        "and 'recurrent_ppo' (a GRU of 25 before it, as Alonso & Kirkegaard's) are trained in "
        "the job by NanoNav's PPO trainer for learning.decisions, on worlds of one robot apart "
        "from the evaluation's, then evaluated greedily as a network given by policy_from, "
        "every robot deciding with it; a worker that trains runs them (`nanonav worker "
        "--train`), and the network is kept as the job's trained_policy.",
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


class Learning(Part):
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

    decisions: int | None = Field(
        None,
        ge=1,
        le=MAX_TRAINING_DECISIONS,
        description="robots.policy 'ppo' or 'recurrent_ppo': the decisions the network is "
        "trained for before it is evaluated, counted over all the trainer's worlds of one "
        "robot (1,024 at once; rounded up to whole rollouts of 65,536). null: 1,000,000. "
        "Other policies leave it unused (their training is learning.episodes), and a network "
        "leaves learning.episodes unused, so that a study's grid may mix learners and rules "
        "over one base scenario.",
    )
    checkpoint_decisions: int | None = Field(
        None,
        ge=65_536,
        le=MAX_TRAINING_DECISIONS,
        description="robots.policy 'ppo' or 'recurrent_ppo': decisions between two "
        "checkpoints of the trainer's state (networks, optimiser, random streams), kept in "
        "the store so that a job whose worker dies resumes from the last one; rounded up to "
        "whole rollouts. null: 5,000,000, about a minute of training. Other policies leave "
        "it unused.",
    )

    @model_validator(mode="after")
    def _epsilon_order(self) -> Learning:
        if self.epsilon_end > self.epsilon_start:
            raise field_error(
                "Learning", ("epsilon_end",), self.epsilon_end, "must not exceed epsilon_start"
            )
        return self


class Rewards(Part):
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


class Evaluation(Part):
    """How the learned (or fixed) policy is judged after training: greedily, in fresh worlds."""

    worlds: int = Field(
        20,
        ge=1,
        le=1000,
        description="Evaluation episodes, each in a fresh world drawn from a stream of its own, "
        "so that every policy run with the same seed is judged in the same worlds. The summary "
        "is the mean over them; the first is recorded for the trajectory and the pictures.",
    )


class Communication(Part):
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
