"""The work model: what the engine's operations cost, in work units (nanoseconds of one core
of the machine they were fitted on), and what a scenario's run costs in them (``most_work``,
``work_for``): what a submit is charged against a key's budget, and what ``python
benchmarks/cost.py`` checks against run time."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from nanonav.scenario.model import Scenario

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
# A network the job trains: the trainer's own work a decision besides the engine's steps (the
# forward pass that decides, the rollout kept, its share of the update), from
# ``python benchmarks/train_speed.py`` at 1,024 worlds on two cores: 2 core-s over 219,000 (MLP)
# and 105,000 (GRU-25) decisions a second, less the 2,000 units the raw env took a decision.
WORK_TRAINING_DECISION = {"ppo": 7_000, "recurrent_ppo": 17_000}


def swarm_robot_step(scenario: Scenario) -> float:
    """What exclusion and signalling add to one active robot's step, in work units."""
    units = WORK_EXCLUSION if scenario.robots.exclusion else 0.0
    model = scenario.communication.model
    if model == "broadcast":
        units += WORK_RELIST
    elif model != "none":
        species = 2 if model == "attractant_repellent" else 1
        units += WORK_SIGNAL_READ * species
    return units


def swarm_step(scenario: Scenario) -> float:
    """What the signal's grid adds to one step, in work units: its nodes at every solver
    step, and a release by every robot (bound or not, each is looked at) at every update."""
    model = scenario.communication.model
    if model in ("none", "broadcast"):
        return 0.0
    every, substeps = scenario.signal_solver_steps
    species = 2 if model == "attractant_repellent" else 1
    grid = WORK_NODE * scenario.communication.nodes_per_axis**3 * species * substeps
    return (grid + WORK_RELEASE * scenario.robots.count) / every


def robot_step_overhead(scenario: Scenario) -> float:
    """C, the work of one robot's step besides its scans and field terms: Q-learning's
    behaviours cost most, the baselines least."""
    if scenario.robots.policy == "q_learning":
        return WORK_ROBOT_STEP[scenario.learning.actions]
    return WORK_ROBOT_STEP["baseline"]


def most_work(scenario: Scenario) -> int:
    """The most this scenario can cost, in work units (about a nanosecond of one core each,
    see the ``WORK_*`` weights): every robot active for every step of every episode.

    Unlike ``robot_steps_budget`` it weighs a robot-step by what it does: a field term per
    source, two scans of the obstacles and of the cells; and it adds what a step, an
    episode and the recorded evaluation cost besides (``work_for``)."""
    episodes = scenario.episodes
    steps = scenario.learning.max_steps * episodes
    evaluation_steps = scenario.learning.max_steps * scenario.evaluation.worlds
    run = work_for(scenario, scenario.robots.count * steps, steps, episodes, evaluation_steps)
    return run + training_work(scenario)


def training_work(scenario: Scenario) -> int:
    """What training a network costs (0 for a policy that trains none): the trainer's work a
    decision, and the engine's steps of its worlds of one robot, each an episode's share of a
    world's draw."""
    decisions = scenario.training_decisions
    if not decisions:
        return 0
    steps = decisions * scenario.decision_steps
    episodes = math.ceil(steps / scenario.learning.max_steps)
    engine = work_for(scenario, steps, steps, episodes, 0)
    return engine + decisions * WORK_TRAINING_DECISION[scenario.robots.policy]


def work_for(
    scenario: Scenario, robot_steps: int, steps: int, episodes: int, evaluation_steps: int
) -> int:
    """The work of a run of this scenario that took ``robot_steps`` robot-steps over
    ``steps`` steps of ``episodes`` episodes, ``evaluation_steps`` of them in the evaluation
    (where the field is also measured at every robot for the metrics)."""
    n = scenario.robots.count
    c = scenario.cells.count
    o = scenario.obstacles.count
    k = scenario.sources
    source = WORK_SOURCE[scenario.biomarker.model]
    # units per active robot and step: sense (k terms), nearest obstacle and the collision
    # test (o tests each), nearest cell before and after the move (c tests each)
    robot_step = robot_step_overhead(scenario) + source * k + 2 * WORK_PAIR * (o + c)
    # units per step: place the sources; a cell moves unless into one of o obstacles; an
    # obstacle moves unless onto one of n robots or c cells
    step = WORK_STEP + WORK_PLACE * k
    if scenario.cells.motion_std > 0:
        step += c * (WORK_DRAW + WORK_PAIR * o)
    if scenario.obstacles.motion_std > 0:
        step += o * (WORK_DRAW + WORK_PAIR * (n + c))
    # units per episode: draw the world (robots clear of cells, obstacles clear of both, at
    # one attempt each; emitter offsets for every model), and close it with one more step of
    # every robot
    emitters = c * scenario.biomarker.emitters_per_cell
    episode = (
        WORK_DRAW * (c + 2 * n + o + emitters) + WORK_PAIR * (n * c + o * (n + c)) + n * robot_step
    )
    robot_step += swarm_robot_step(scenario)
    step += swarm_step(scenario)
    # a broadcast reaches the robots in the 27 cells of the radio's list around its sender:
    # at most every robot delivers once an episode, each message scanning that share
    if scenario.communication.model == "broadcast":
        share = min(1.0, (3 * scenario.communication.range / scenario.space.size) ** 3)
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


# Robots stepped at once: the worlds are evaluated in rounds of at most this many robots (or
# one world, if it has more), so that memory grows with a round, not with worlds x robots
ROUND_ROBOTS = 100_000


# What deciding by a network costs, in the work units of ``Scenario.work`` (about a nanosecond
# of one core), fitted on benchmarks/network_policy.py's networks (MLPs of 16 to 700 units, an
# LSTM of 256) run in their sandboxed process: a call (the observations out and the answers
# back, two processes woken), a row of it (its observation gathered and its answer checked),
# and a multiply-add the network's check counted (an LSTM's run slowest, 0.025-0.04 ns)
WORK_NETWORK_CALL = 250_000
WORK_NETWORK_ROW = 60
WORK_MULTIPLY_ADD = 0.04


def decision_work(scenario: Scenario, multiply_adds: int) -> int:
    """The work of a network of ``multiply_adds`` an observation deciding in ``scenario``'s
    evaluation: every robot of every world at every decision, in one call a decision for
    every world of a round (a call for each robot's turn under the sequential schedule)."""
    robots = scenario.robots.count
    worlds = scenario.evaluation.worlds
    decisions = math.ceil(scenario.learning.max_steps / scenario.decision_steps)
    rounds = math.ceil(worlds / max(1, ROUND_ROBOTS // robots))
    calls = rounds * decisions * (1 if decides_at_once(scenario) else robots)
    rows = worlds * robots * decisions
    total = calls * WORK_NETWORK_CALL + rows * (
        WORK_NETWORK_ROW + WORK_MULTIPLY_ADD * multiply_adds
    )
    return math.ceil(total)


REMEMBERS_AT_ONCE = (
    "a network with a memory decides for every robot at once, each row one robot: "
    "robots.schedule must be 'simultaneous'"
)


def decides_at_once(scenario: Scenario) -> bool:
    """Whether every robot of a world decides in each call (the simultaneous schedule, or one
    robot), so that row k is the same robot call after call."""
    return scenario.robots.schedule == "simultaneous" or scenario.robots.count == 1
