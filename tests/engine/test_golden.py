"""Golden digests of ``simulate``: what a short run of each case gives, pinned bit for bit, so
that a change to the step that moves a result is seen, and explained, before it lands.

A case's digest is the SHA-256 of its metrics (the evaluation's summary, worlds and robots and
the training curve, all but wall-clock times) and of every array of its trajectory and Q-table,
dtype and shape included; its summary is kept beside it in ``golden_digests.json`` for a reader
to see what moved. The cases span every preset, both physics, every policy of each, every
action set, every communication model of each physics, exclusion, treatment, moving obstacles
and per-robot tables.

    python -m tests.engine.test_golden    # write golden_digests.json anew from this code
"""

from __future__ import annotations

import functools
import hashlib
import json
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from nanonav.engine import simulate
from nanonav.engine.result import SimulationResult, without_timings
from nanonav.scenario import (
    BROWNIAN_POLICIES,
    LATTICE_POLICIES,
    PRESETS,
    TRAINED_POLICIES,
    Scenario,
    deep_merge,
)

GOLDEN = Path(__file__).with_name("golden_digests.json")

SHORT: dict[str, Any] = {"learning": {"episodes": 2, "max_steps": 60}, "evaluation": {"worlds": 3}}
SHORT_SI: dict[str, Any] = {
    "physics": {"time_limit_s": 0.6},
    "learning": {"episodes": 2},
    "evaluation": {"worlds": 2},
}
SWARM: dict[str, Any] = {"robots": {"count": 6}, "cells": {"count": 2}}
# Reading each step, the sensor before molecules were counted: these cases' digests are older
# than counting, and the same again after it became the default.
MICROSWIMMERS: dict[str, Any] = {
    "preset": "tumour-microswimmers",
    "robots": {"count": 6},
    "physics": {"sensor": "each_step"},
}
COUNTED: dict[str, Any] = {"physics": {"sensor": "counted"}}
# Robots that reach the cell (and bind, and signal) within a short run.
CROWDED: dict[str, Any] = {
    "space": {"size": 40.0},
    "obstacles": {"count": 2},
    "physics": {"time_limit_s": 6.0},
    "robots": {"policy": "exact_gradient"},
}
# A cell treated by its first delivery: the repellent of 'attractant_repellent' is released.
TREATED: dict[str, Any] = {"cells": {"capacity": 1}}


def _merge(*parts: dict[str, Any]) -> dict[str, Any]:
    return functools.reduce(deep_merge, parts, {})


def _cases() -> dict[str, dict[str, Any]]:
    cases: dict[str, dict[str, Any]] = {}
    for name, preset in PRESETS.items():
        brownian = preset.get("physics", {}).get("model") == "active_brownian"
        robots = {"robots": {"count": min(preset.get("robots", {}).get("count", 1), 8)}}
        cases[f"preset {name}"] = _merge({"preset": name}, SHORT_SI if brownian else SHORT, robots)
    for policy in sorted(LATTICE_POLICIES - TRAINED_POLICIES):  # those the engine runs
        cases[f"lattice {policy}"] = _merge(SHORT, SWARM, {"robots": {"policy": policy}})
    cases["lattice q_learning directions"] = _merge(SHORT, {"learning": {"actions": "directions"}})
    for model in ("attractant", "attractant_repellent", "broadcast"):
        cases[f"lattice signal {model}"] = _merge(
            SHORT, SWARM, TREATED, {"communication": {"model": model}}
        )
    cases["lattice exclusion and treatment"] = _merge(
        SHORT, SWARM, {"robots": {"exclusion": True}, "cells": {"capacity": 2}}
    )
    cases["lattice per-robot tables, moving obstacles"] = _merge(
        SHORT,
        SWARM,
        {"learning": {"shared_table": False}, "obstacles": {"count": 8, "motion_std": 0.1}},
    )
    cases["lattice noisy sensing"] = _merge(
        SHORT, {"biomarker": {"sensor_noise": 0.1, "model": "inverse_square"}}
    )
    cases["lattice diffusion field"] = _merge(SHORT, SWARM, {"biomarker": {"model": "diffusion"}})
    for policy in sorted(BROWNIAN_POLICIES - TRAINED_POLICIES):
        cases[f"active_brownian {policy}"] = _merge(
            MICROSWIMMERS, SHORT_SI, {"robots": {"policy": policy}}
        )
    for policy in sorted(BROWNIAN_POLICIES - TRAINED_POLICIES):
        cases[f"active_brownian counted {policy}"] = _merge(
            MICROSWIMMERS, SHORT_SI, COUNTED, {"robots": {"policy": policy}}
        )
    for model in ("attractant", "attractant_repellent", "broadcast"):
        cases[f"active_brownian signal {model}"] = _merge(
            MICROSWIMMERS, SHORT_SI, TREATED, CROWDED, {"communication": {"model": model}}
        )
    for model in ("attractant", "attractant_repellent"):
        cases[f"active_brownian counted signal {model}"] = _merge(
            MICROSWIMMERS, SHORT_SI, TREATED, CROWDED, COUNTED, {"communication": {"model": model}}
        )
    cases["active_brownian treatment, per-robot tables"] = _merge(
        MICROSWIMMERS,
        SHORT_SI,
        {"cells": {"capacity": 2}, "learning": {"shared_table": False}},
    )
    return cases


CASES = _cases()


def digest(result: SimulationResult) -> str:
    """SHA-256 of a result's metrics (without wall-clock times) and arrays, bit for bit."""
    hashed = hashlib.sha256()
    metrics = {
        "summary": result.summary,
        "worlds": result.worlds,
        "robots": result.robots,
        "episodes": result.episodes,
    }
    hashed.update(json.dumps(without_timings(metrics), sort_keys=True).encode())
    for name, value in sorted(result.arrays().items()):
        contiguous = np.ascontiguousarray(value)
        hashed.update(f"{name}{contiguous.dtype.str}{contiguous.shape}".encode())
        hashed.update(contiguous.tobytes())
    return hashed.hexdigest()


def run(case: str) -> dict[str, Any]:
    result = simulate(Scenario.model_validate(CASES[case]))
    return {"summary": without_timings(result.summary), "digest": digest(result)}


def _stored() -> dict[str, Any]:
    stored: dict[str, Any] = json.loads(GOLDEN.read_text())
    return stored


@pytest.mark.parametrize("case", sorted(CASES))
def test_a_short_run_gives_its_golden_digest(case: str) -> None:
    golden = _stored()
    assert case in golden, f"no digest for {case!r}: python -m tests.engine.test_golden"
    got = run(case)
    assert got["summary"] == golden[case]["summary"]
    assert got["digest"] == golden[case]["digest"], "the metrics agree, an array does not"


def test_every_golden_digest_has_its_case() -> None:
    assert sorted(_stored()) == sorted(CASES)


def test_the_digest_sees_a_change_of_one_bit() -> None:
    result = simulate(Scenario.model_validate(CASES["preset paper-single"]))
    before = digest(result)
    assert result.qtable is not None
    result.qtable.values.view(np.uint64).reshape(-1)[0] ^= 1
    assert digest(result) != before


if __name__ == "__main__":
    GOLDEN.write_text(json.dumps({case: run(case) for case in sorted(CASES)}, indent=1) + "\n")
    print(f"wrote {len(CASES)} digests to {GOLDEN}", file=sys.stderr)
