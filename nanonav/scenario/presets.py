"""The presets: the paper's worlds, the authors' script's, worlds of honest sensing, the
physical question's and the swarm's, as the values each lays under a request."""

from __future__ import annotations

import math
from typing import Any

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
