"""The names a scenario chooses among: presets, field models, policies, action sets, physics,
sensors, communication, steering; and which policies each physics runs."""

from __future__ import annotations

from typing import Literal

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
    "ppo",
    "recurrent_ppo",
]
AlphaSchedule = Literal["constant", "visits"]
ActionSet = Literal["behaviors", "directions", "steering"]
PhysicsModel = Literal["lattice", "active_brownian"]
Sensor = Literal["each_step", "counted"]


CommunicationModel = Literal["none", "attractant", "attractant_repellent", "broadcast"]
# The deep learners a job trains (a worker that trains, ``nanonav worker --train``), in either
# physics: ``ppo`` a network without memory, ``recurrent_ppo`` one with a GRU before it.
TRAINED_POLICIES = frozenset({"ppo", "recurrent_ppo"})
# What each physics runs: the paper's lattice moves choose a direction; an active Brownian robot
# can only steer its own diffusing heading.
LATTICE_POLICIES = frozenset({"q_learning", "gradient", "run_and_tumble", "rule", "simple_rule",
                              "random", *TRAINED_POLICIES})  # fmt: skip
BROWNIAN_POLICIES = frozenset({"q_learning", "uncontrolled", "run_and_tumble", "gradient",
                               "exact_gradient", "steer_and_tumble", "blind_tumble",
                               *TRAINED_POLICIES})  # fmt: skip
