"""The scenario: one validated, documented description of a simulation run.

The same schema is used unchanged by the library, the ``nanonav`` command and the REST API.
Every field has a default and a bound, unknown keys are rejected, and a ``preset`` supplies base
values that explicit fields override. Two physics: ``lattice`` (the paper's), where lengths are in
simulation units (the paper's cube is 50 units a side), times in steps and concentrations in
arbitrary units relative to ``biomarker.peak``; and ``active_brownian``, where every length is in
µm, every time in s (a step is ``physics.dt_s``) and every concentration in nM, and the
quantities only it has carry their unit in their name (``physics``).

Its files: ``choices`` (the names a field chooses among), ``limits`` (shared bounds and
defaults), ``base`` (strict parts and cross-field errors), ``parts`` (space, cells, biomarker,
obstacles, robots, learning, rewards, evaluation, communication), ``physics`` (the physics
part), ``work`` (the work model's costs), ``presets`` and ``model`` (the scenario itself and
``preset_scenario``). The physical formulas both the schema and the engine use are
``nanonav.physics``. Everything public is importable from here.
"""

from nanonav.physics import (
    AVOGADRO_PER_MOL,
    BOLTZMANN_J_K,
    DT_FLOOR_S,
    LARGEST_AUTOMATIC_DT_S,
    MOLECULES_PER_UM3_PER_NM,
    automatic_dt_s,
    crossing_time_s,
    rounded_down,
    stokes_einstein_debye_s,
    stokes_einstein_um2_s,
    time_limit_steps,
    time_step_bounds,
)
from nanonav.scenario.base import Part, ScenarioError, admits, field_error, integer_fields, whole
from nanonav.scenario.choices import (
    BROWNIAN_POLICIES,
    LATTICE_POLICIES,
    STEERINGS,
    ActionSet,
    AlphaSchedule,
    CommunicationModel,
    FieldModel,
    PhysicsModel,
    Policy,
    PresetName,
    RobotStart,
    Schedule,
    Sensor,
    Steering,
)
from nanonav.scenario.limits import (
    BROWNIAN_ALPHA_EXPONENT,
    BROWNIAN_DECISION_INTERVAL_S,
    BROWNIAN_SIGNAL,
    DEFAULT_INTEGRATION_TIME_S,
    DENSEST_PACKING,
    LARGEST_DECAY_RATE,
    LATTICE_SIGNAL,
    MAX_EXACT_INT,
    MAX_OBSTACLE_VOLUME_FRACTION,
    MAX_ROBOT_VOLUME_FRACTION,
    MAX_SIGNAL_EVERY,
    MAX_STEPS,
)
from nanonav.scenario.model import LATTICE_ONLY, Scenario, preset_scenario
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
from nanonav.scenario.presets import (
    ALONSO_KIRKEGAARD,
    DIFFUSE_TUMOUR,
    HARD,
    PRESETS,
    TUMOUR,
    deep_merge,
)
from nanonav.scenario.work import (
    WORK_DRAW,
    WORK_EXCLUSION,
    WORK_NODE,
    WORK_PAIR,
    WORK_PLACE,
    WORK_RELEASE,
    WORK_RELIST,
    WORK_ROBOT_STEP,
    WORK_SIGNAL_READ,
    WORK_SOURCE,
    WORK_STEP,
)

__all__ = [
    "ALONSO_KIRKEGAARD",
    "AVOGADRO_PER_MOL",
    "BOLTZMANN_J_K",
    "BROWNIAN_ALPHA_EXPONENT",
    "BROWNIAN_DECISION_INTERVAL_S",
    "BROWNIAN_POLICIES",
    "BROWNIAN_SIGNAL",
    "DEFAULT_INTEGRATION_TIME_S",
    "DENSEST_PACKING",
    "DIFFUSE_TUMOUR",
    "DT_FLOOR_S",
    "HARD",
    "LARGEST_AUTOMATIC_DT_S",
    "LARGEST_DECAY_RATE",
    "LATTICE_ONLY",
    "LATTICE_POLICIES",
    "LATTICE_SIGNAL",
    "MAX_EXACT_INT",
    "MAX_OBSTACLE_VOLUME_FRACTION",
    "MAX_ROBOT_VOLUME_FRACTION",
    "MAX_SIGNAL_EVERY",
    "MAX_STEPS",
    "MOLECULES_PER_UM3_PER_NM",
    "PRESETS",
    "STEERINGS",
    "TUMOUR",
    "WORK_DRAW",
    "WORK_EXCLUSION",
    "WORK_NODE",
    "WORK_PAIR",
    "WORK_PLACE",
    "WORK_RELEASE",
    "WORK_RELIST",
    "WORK_ROBOT_STEP",
    "WORK_SIGNAL_READ",
    "WORK_SOURCE",
    "WORK_STEP",
    "ActionSet",
    "AlphaSchedule",
    "Biomarker",
    "Cells",
    "Communication",
    "CommunicationModel",
    "Evaluation",
    "FieldModel",
    "Learning",
    "Obstacles",
    "Part",
    "Physics",
    "PhysicsModel",
    "Policy",
    "PresetName",
    "Rewards",
    "RobotStart",
    "Robots",
    "Scenario",
    "ScenarioError",
    "Schedule",
    "Sensor",
    "Space",
    "Steering",
    "admits",
    "automatic_dt_s",
    "crossing_time_s",
    "deep_merge",
    "field_error",
    "fill_physics",
    "integer_fields",
    "preset_scenario",
    "rounded_down",
    "stokes_einstein_debye_s",
    "stokes_einstein_um2_s",
    "time_limit_steps",
    "time_step_bounds",
    "whole",
]
