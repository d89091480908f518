"""The physics section of a scenario: Stokes-Einstein(-Debye) defaults filled in, time steps that
resolve the motion, and each physics refusing what only the other has a use for, naming the
field."""

from __future__ import annotations

import math
from typing import Any

import pytest
from pydantic import ValidationError

from nanonav.scenario import Scenario, stokes_einstein_debye_s, stokes_einstein_um2_s

BROWNIAN = {"physics": {"model": "active_brownian"}}


def refused(data: dict[str, Any]) -> tuple[tuple[str | int, ...], str]:
    with pytest.raises(ValidationError) as caught:
        Scenario.model_validate(data)
    error = caught.value.errors()[0]
    return tuple(error["loc"]), error["msg"]


def test_diffusion_defaults_to_stokes_einstein_and_is_stored_filled_in() -> None:
    s = Scenario.model_validate(
        {"physics": {"model": "active_brownian", "robot_radius_um": 2.0, "dt_s": 0.02}}
    )
    assert s.physics.diffusion_um2_s == pytest.approx(stokes_einstein_um2_s(310.15, 0.69, 2.0))
    assert s.physics.rotational_diffusion_s == pytest.approx(
        stokes_einstein_debye_s(310.15, 0.69, 2.0)
    )
    assert s.physics.diffusion_um2_s == pytest.approx(0.3292 / 2, rel=1e-3)
    dumped = s.model_dump(mode="json")
    assert dumped["physics"]["diffusion_um2_s"] == s.physics.diffusion_um2_s
    assert Scenario.model_validate(dumped) == s  # what is stored validates again, unchanged
    given = Scenario.model_validate(
        {
            "physics": {
                "model": "active_brownian",
                "diffusion_um2_s": 0.1,
                "rotational_diffusion_s": 0.5,
            }
        }
    )
    assert (given.physics.diffusion_um2_s, given.physics.rotational_diffusion_s) == (0.1, 0.5)
    assert given.learning.actions == "steering"
    assert Scenario().physics.diffusion_um2_s is None  # the lattice physics has none


@pytest.mark.parametrize(
    ("physics", "broken"),
    [
        ({"dt_s": 1.0}, "D_R dt"),  # the heading turns too far in a step
        ({"swim_speed_um_s": 200.0, "dt_s": 0.01}, "would swim"),  # 2 um a step
        ({"diffusion_um2_s": 20.0, "rotational_diffusion_s": 0.1, "dt_s": 0.01}, "jiggle"),
    ],
)
def test_a_time_step_too_coarse_is_refused_with_one_that_would_do(
    physics: dict[str, Any], broken: str
) -> None:
    loc, message = refused({"physics": {"model": "active_brownian", **physics}})
    assert loc == ("physics", "dt_s") and broken in message
    suggested = float(message.rsplit("dt_s <= ", 1)[1].split(" s")[0])
    fixed = Scenario.model_validate(
        {"physics": {"model": "active_brownian", **physics, "dt_s": suggested}}
    )
    assert fixed.physics.dt_s == suggested


def test_a_small_robot_needs_a_short_step() -> None:
    # a 0.1 um sphere forgets its heading at D_R = 247 1/s: 0.01 s is far too coarse
    loc, message = refused(
        {"physics": {"model": "active_brownian", "robot_radius_um": 0.1, "dt_s": 0.01}}
    )
    assert loc == ("physics", "dt_s") and "2.47" in message and "0.0002" in message


@pytest.mark.parametrize(
    ("extra", "field"),
    [
        ({"robots": {"speed": 2.0}}, ("robots", "speed")),
        ({"robots": {"sensor_baseline": 1.0}}, ("robots", "sensor_baseline")),
        ({"robots": {"sensing_radius": 3.0}}, ("robots", "sensing_radius")),
        ({"cells": {"motion_std": 0.5}}, ("cells", "motion_std")),
        ({"obstacles": {"motion_std": 0.5}}, ("obstacles", "motion_std")),
        ({"biomarker": {"noise_floor": 0.1}}, ("biomarker", "noise_floor")),
        ({"biomarker": {"model": "gaussian", "spread": 3.0}}, ("biomarker", "spread")),
        ({"reach_distance": 2.0}, ("reach_distance",)),
        ({"robots": {"policy": "rule"}}, ("robots", "policy")),
        ({"learning": {"actions": "behaviors"}}, ("learning", "actions")),
    ],
)
def test_active_brownian_refuses_what_only_the_lattice_uses(
    extra: dict[str, Any], field: tuple[str, ...]
) -> None:
    loc, message = refused({**BROWNIAN, **extra})
    assert loc == field, message
    assert "active_brownian" in message


@pytest.mark.parametrize(
    ("physics", "field"),
    [
        ({"dt_s": 0.1}, "dt_s"),
        ({"robot_radius_um": 2.0}, "robot_radius_um"),
        ({"diffusion_um2_s": 1.0}, "diffusion_um2_s"),
    ],
)
def test_the_lattice_refuses_what_only_active_brownian_uses(
    physics: dict[str, Any], field: str
) -> None:
    loc, message = refused({"physics": physics})
    assert loc == ("physics", field) and "active_brownian" in message
    loc, _ = refused({"robots": {"policy": "uncontrolled"}})
    assert loc == ("robots", "policy")
    loc, _ = refused({"learning": {"actions": "steering"}})
    assert loc == ("learning", "actions")


def test_every_physical_default_is_finite_and_in_its_own_bounds() -> None:
    s = Scenario.model_validate(BROWNIAN)
    for name, value in s.physics.model_dump().items():
        if isinstance(value, float):
            assert math.isfinite(value), name


@pytest.mark.parametrize("radius", [0.2, 1.0, 5.0])
def test_the_time_step_defaults_to_the_largest_that_resolves_the_motion(radius: float) -> None:
    s = Scenario.model_validate(
        {"physics": {"model": "active_brownian", "robot_radius_um": radius, "time_limit_s": 60}}
    )
    dt = s.physics.dt_s
    assert dt is not None and dt <= 0.01
    d_r = s.physics.rotational_diffusion_s
    assert d_r is not None and d_r * dt <= 0.05
    # and not much smaller than it need be: the next step up would break a bound or the cap
    coarser = dt * 1.2
    if coarser <= 0.01:
        with pytest.raises(ValidationError):
            Scenario.model_validate(
                {
                    "physics": {
                        "model": "active_brownian",
                        "robot_radius_um": radius,
                        "dt_s": coarser,
                    }
                }
            )
    assert s.learning.max_steps == math.ceil(60 / dt - 1e-9)  # the time limit in steps
    assert Scenario.model_validate(s.model_dump(mode="json")) == s


def test_a_time_limit_and_a_different_step_limit_are_refused() -> None:
    loc, message = refused(
        {"physics": {"model": "active_brownian", "time_limit_s": 10}, "learning": {"max_steps": 5}}
    )
    assert loc == ("learning", "max_steps") and "time_limit_s" in message


@pytest.mark.parametrize("name", ["tumour-microswimmers", "tumour-nanorobots", "tumour-passive"])
def test_the_physical_presets_are_active_brownian_worlds_in_um_and_s(name: str) -> None:
    s = Scenario.model_validate({"preset": name})
    assert s.physics.model == "active_brownian" and s.learning.actions == "steering"
    assert s.space.size == 150.0 and s.obstacles.radius == 5.0 and s.robots.count == 20
    assert s.physics.time_limit_s == 60.0
    assert s.learning.max_steps * s.physics.step_s == pytest.approx(60.0, abs=s.physics.step_s)
    assert Scenario.model_validate(s.model_dump(mode="json")) == s
