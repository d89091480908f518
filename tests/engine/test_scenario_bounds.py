"""The bounds of a scenario's physical fields: whatever the schema admits resolves to derived
physics that is finite and positive (D_T, D_R, dt_s, the step limit, the signal's rates and
solver steps, the work, the kernel's constants), and anything else is a ValidationError naming
a field that was sent, never a field derived from it and never another exception."""

from __future__ import annotations

import math
from typing import Any

import pytest
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st
from pydantic import ValidationError

from nanonav.engine.fields import MODEL_CODES
from nanonav.engine.simulation import kernel_params
from nanonav.scenario import (
    BROWNIAN_POLICIES,
    BROWNIAN_SIGNAL,
    LATTICE_SIGNAL,
    PRESETS,
    Physics,
    Scenario,
    fill_physics,
    preset_scenario,
    stokes_einstein_debye_s,
    stokes_einstein_um2_s,
)
from nanonav.studies.spec import StudySpec, points

SCHEMA = Scenario.model_json_schema()
DEFS: dict[str, dict[str, Any]] = SCHEMA["$defs"]
# Floats that break arithmetic: subnormals, the smallest normal, the huge, the largest.
EXTREMES = (5e-324, 1e-310, 2.2250738585072014e-308, 1e-120, 1e120, 1e308, 1.7976931348623157e308)
# What validation fills in: an error there names a field the user never sent.
DERIVED = {
    ("physics", "diffusion_um2_s"),
    ("physics", "rotational_diffusion_s"),
    ("physics", "dt_s"),
    ("learning", "max_steps"),
    ("learning", "actions"),
}
DT_FLOOR_S = 1e-9
MAX_STEPS = 1_000_000
NO_RECORD_CAP = 2**62
EXAMPLES = settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])


def _admits(spec: dict[str, Any], value: float) -> bool:
    """Whether a JSON Schema number ``spec`` admits ``value``."""
    admitted: bool = (
        spec.get("minimum", -math.inf) <= value <= spec.get("maximum", math.inf)
        and value > spec.get("exclusiveMinimum", -math.inf)
        and value < spec.get("exclusiveMaximum", math.inf)
    )
    return admitted


def _numbers(spec: dict[str, Any]) -> st.SearchStrategy[float]:
    """Any number ``spec`` admits, its bounds, the values next to them and the extreme ones
    within them drawn often."""
    low = spec.get("minimum", spec.get("exclusiveMinimum", -1e308))
    high = spec.get("maximum", spec.get("exclusiveMaximum", 1e308))
    near = (low, high, math.nextafter(low, math.inf), math.nextafter(high, -math.inf))
    edges = [float(v) for v in (*near, *EXTREMES) if _admits(spec, v)]
    inside = st.floats(
        min_value=low,
        max_value=high,
        exclude_min="exclusiveMinimum" in spec,
        exclude_max="exclusiveMaximum" in spec,
    )
    return st.one_of(st.sampled_from(edges), inside)


def from_schema(spec: dict[str, Any], keys: int = 3) -> st.SearchStrategy[Any]:
    """Values of the JSON Schema ``spec`` (the subset pydantic writes); an object gets at most
    ``keys`` of its properties, so that a scenario is not refused for everything at once."""
    if "$ref" in spec:
        return from_schema(DEFS[spec["$ref"].rpartition("/")[2]], keys)
    if "anyOf" in spec:
        return st.one_of(*(from_schema(branch, keys) for branch in spec["anyOf"]))
    if "enum" in spec:
        return st.sampled_from(spec["enum"])
    if "const" in spec:
        return st.just(spec["const"])
    kind = spec.get("type")
    if kind == "null":
        return st.none()
    if kind == "boolean":
        return st.booleans()
    if kind == "integer":
        return st.integers(spec.get("minimum"), spec.get("maximum"))
    if kind == "number":
        return _numbers(spec)
    if kind == "string":
        return st.from_regex(spec["pattern"], fullmatch=True)
    assert kind == "object", spec
    return sections(spec["properties"], sorted(spec["properties"]), keys)


def sections(
    properties: dict[str, Any], names: list[str], keys: int
) -> st.SearchStrategy[dict[str, Any]]:
    """Dictionaries of at most ``keys`` of ``names``, each valued from its schema."""
    chosen = st.sets(st.sampled_from(names), max_size=keys)
    return chosen.flatmap(
        lambda picked: st.fixed_dictionaries(
            {name: from_schema(properties[name]) for name in sorted(picked)}
        )
    )


def _part(name: str, leave_out: tuple[str, ...] = ()) -> tuple[dict[str, Any], list[str]]:
    properties = DEFS[name]["properties"]
    return properties, [k for k in sorted(properties) if k not in leave_out]


def brownian_scenarios() -> st.SearchStrategy[dict[str, Any]]:
    """Active Brownian scenarios: a physical preset or none, any physics and signal the
    schema admits (in the physics' own units), and a policy of the physics."""
    physics, physics_names = _part("Physics", ("model",))
    comm, comm_names = _part("Communication", LATTICE_SIGNAL)
    space, _ = _part("Space")
    return st.fixed_dictionaries(
        {
            "physics": sections(physics, physics_names, 6).map(
                lambda p: {**p, "model": "active_brownian"}
            ),
        },
        optional={
            "preset": st.sampled_from(
                ["tumour-microswimmers", "tumour-nanorobots", "tumour-passive"]
            ),
            "communication": sections(comm, comm_names, 4),
            "space": sections(space, ["size"], 1),
            "robots": st.fixed_dictionaries({"policy": st.sampled_from(sorted(BROWNIAN_POLICIES))}),
        },
    )


def lattice_scenarios() -> st.SearchStrategy[dict[str, Any]]:
    """Lattice scenarios: any world the schema admits, any signal in lattice units."""
    comm, comm_names = _part("Communication", BROWNIAN_SIGNAL)
    parts = {
        name: from_schema(SCHEMA["properties"][name])
        for name in ("space", "cells", "biomarker", "obstacles", "robots")
    }
    return st.fixed_dictionaries(
        {"communication": sections(comm, comm_names, 4)},
        optional={**parts, "reach_distance": from_schema(SCHEMA["properties"]["reach_distance"])},
    )


def _sent(data: dict[str, Any], loc: tuple[str | int, ...]) -> bool:
    """Whether the data (or the preset it names) holds the field at ``loc``."""
    for source in (data, PRESETS.get(str(data.get("preset")), {})):
        value: Any = source
        for part in loc:
            if not isinstance(value, dict) or part not in value:
                break
            value = value[part]
        else:
            return True
    return False


def _finite(value: Any) -> bool:
    return isinstance(value, int | float) and math.isfinite(value)


def assert_physical(s: Scenario) -> None:
    """Every quantity derived from ``s`` is finite, and positive where it means to be."""
    ph = s.physics
    if ph.model == "active_brownian":
        for value in (ph.diffusion_um2_s, ph.rotational_diffusion_s):
            assert value is not None and _finite(value) and value >= 0.0
        assert ph.dt_s is not None and DT_FLOOR_S <= ph.dt_s <= 10.0
        if ph.time_limit_s is not None:
            assert s.learning.max_steps == max(1, math.ceil(ph.time_limit_s / ph.dt_s - 1e-9))
    else:
        assert (ph.diffusion_um2_s, ph.rotational_diffusion_s, ph.dt_s) == (None, None, None)
    assert 1 <= s.learning.max_steps <= MAX_STEPS
    diffusion, decay, release = s.signal_rates
    assert _finite(diffusion) and diffusion > 0.0
    assert _finite(decay) and decay >= 0.0
    assert _finite(release) and release > 0.0
    every, substeps = s.signal_solver_steps
    assert every >= 1 and substeps >= 1
    assert isinstance(s.work, int) and s.work > 0
    assert s.robot_steps_budget > 0
    # a network the job trains runs in the engine as a network given by policy_from does
    params = kernel_params(s.network_scenario() if s.trains else s, NO_RECORD_CAP)
    for name, value in params._asdict().items():
        assert _finite(value), (name, value)
    assert Scenario.model_validate(s.model_dump(mode="json")) == s


def resolve(data: dict[str, Any]) -> Scenario | None:
    """The scenario ``data`` resolves to, checked, or None when it is refused, with every
    error on a field that was sent or on a rule's field, never on one validation derived."""
    try:
        s = Scenario.model_validate(data)
    except ValidationError as error:
        for e in error.errors():
            loc = tuple(e["loc"])
            assert loc not in DERIVED or _sent(data, loc), (data, e)
        event("refused")
        return None
    event(f"resolved, {s.physics.model}")
    assert_physical(s)
    return s


def refused_at(data: dict[str, Any]) -> list[str]:
    with pytest.raises(ValidationError) as caught:
        Scenario.model_validate(data)
    return [".".join(str(p) for p in e["loc"]) for e in caught.value.errors()]


@pytest.mark.parametrize(
    ("physics", "field"),
    [
        ({"viscosity_mpa_s": 1e-310}, "physics.viscosity_mpa_s"),
        ({"viscosity_mpa_s": 5e-324}, "physics.viscosity_mpa_s"),
        ({"viscosity_mpa_s": 0.005}, "physics.viscosity_mpa_s"),
        ({"robot_radius_um": 1e-120}, "physics.robot_radius_um"),
        ({"dt_s": 5e-324}, "physics.dt_s"),
        ({"time_limit_s": 5e-324}, "physics.time_limit_s"),
        ({"temperature_k": 1e308}, "physics.temperature_k"),
        ({"molecule_diffusion_um2_s": 1e-310}, "physics.molecule_diffusion_um2_s"),
        ({"decay_rate_s": 1e-310}, "physics.decay_rate_s"),
        ({"secretion_molecules_s": 1e-310}, "physics.secretion_molecules_s"),
    ],
)
def test_a_tiny_or_huge_physical_value_is_refused_naming_it_alone(
    physics: dict[str, Any], field: str
) -> None:
    assert refused_at({"preset": "tumour-nanorobots", "physics": physics}) == [field]
    assert refused_at({"physics": {"model": "active_brownian", **physics}}) == [field]
    with pytest.raises(ValidationError) as caught:
        preset_scenario("tumour-nanorobots", physics=physics)
    assert [".".join(map(str, e["loc"])) for e in caught.value.errors()] == [field]


@pytest.mark.parametrize(
    "name", ["temperature_k", "viscosity_mpa_s", "robot_radius_um", "swim_speed_um_s"]
)
def test_fill_physics_never_raises_and_leaves_what_is_out_of_bounds_unfilled(name: str) -> None:
    spec = DEFS["Physics"]["properties"][name]
    numbers = (*EXTREMES, *(-v for v in EXTREMES), 0.0, 0.005, 500.0, math.inf, math.nan)
    for value in (*(v for v in numbers if not _admits(spec, v)), "0.69", None, True, [1.0]):
        data = {"model": "active_brownian", name: value}
        assert fill_physics(data) is data, value
    filled = fill_physics({"model": "active_brownian", name: Physics.model_fields[name].default})
    assert {"diffusion_um2_s", "rotational_diffusion_s", "dt_s"} <= set(filled)


def test_the_stokes_einstein_values_of_every_admitted_world_are_in_bounds() -> None:
    # the fastest diffusion the bounds allow: the smallest robot in the thinnest fluid, hottest
    corner = {"temperature_k": 400.0, "viscosity_mpa_s": 0.01, "robot_radius_um": 0.01}
    s = Scenario.model_validate(
        {"physics": {"model": "active_brownian", "time_limit_s": 1e-3, **corner}}
    )
    assert s.physics.diffusion_um2_s == pytest.approx(stokes_einstein_um2_s(400.0, 0.01, 0.01))
    assert s.physics.rotational_diffusion_s == pytest.approx(
        stokes_einstein_debye_s(400.0, 0.01, 0.01)
    )
    assert s.physics.dt_s is not None and s.physics.dt_s >= DT_FLOOR_S
    assert_physical(s)
    for name in ("diffusion_um2_s", "rotational_diffusion_s"):  # and given, they are admitted
        Physics.model_validate({"model": "active_brownian", name: getattr(s.physics, name)})


@pytest.mark.parametrize(
    ("physics", "field"),
    [
        # a 10 nm robot in water turns in microseconds: 60 s is 3e8 steps of them
        ({"robot_radius_um": 0.01}, "physics.time_limit_s"),
        ({"time_limit_s": 1e6}, "physics.time_limit_s"),
        ({"dt_s": DT_FLOOR_S}, "physics.dt_s"),
    ],
)
def test_a_time_limit_of_more_steps_than_allowed_names_the_time_it_comes_from(
    physics: dict[str, Any], field: str
) -> None:
    with pytest.raises(ValidationError) as caught:
        Scenario.model_validate({"preset": "tumour-nanorobots", "physics": physics})
    errors = caught.value.errors()
    assert [".".join(map(str, e["loc"])) for e in errors] == [field]
    assert "steps" in errors[0]["msg"] and "1000000" in errors[0]["msg"].replace(",", "")


@pytest.mark.parametrize(
    ("grid", "loc", "named"),
    [
        ({"physics.viscosity_mpa_s": [1e-310]}, ("physics.viscosity_mpa_s", 0), "viscosity"),
        (
            {"physics.viscosity_mpa_s": [0.69, 1e-310], "physics.robot_radius_um": [0.2]},
            ("physics.viscosity_mpa_s", 1),
            "viscosity",
        ),
        ({"physics.robot_radius_um": [0.2, 1e-120]}, ("physics.robot_radius_um", 1), "radius"),
        # a radius whose motion needs too fine a step for the preset's 60 s
        ({"physics.robot_radius_um": [0.01]}, ("physics.robot_radius_um", 0), "time_limit_s"),
    ],
)
def test_a_study_grid_of_unphysical_values_is_refused_at_the_grid_value(
    grid: dict[str, list[float]], loc: tuple[str, int], named: str
) -> None:
    spec = StudySpec.model_validate(
        {"base": {"preset": "tumour-nanorobots"}, "grid": grid, "replicates": 1}
    )
    with pytest.raises(ValidationError) as caught:
        points(spec)
    error = caught.value.errors()[0]
    assert error["loc"] == ("grid", *loc) and named in error["msg"]


def test_every_preset_and_default_resolves_to_finite_physics() -> None:
    for name in PRESETS:
        assert_physical(preset_scenario(name))
    assert_physical(Scenario())
    assert_physical(Scenario.model_validate({"physics": {"model": "active_brownian"}}))


@EXAMPLES
@given(from_schema(SCHEMA))
def test_any_scenario_the_schema_admits_resolves_to_finite_physics_or_is_refused(
    data: dict[str, Any],
) -> None:
    resolve(data)


@EXAMPLES
@given(brownian_scenarios())
def test_any_active_brownian_physics_resolves_to_finite_physics_or_is_refused(
    data: dict[str, Any],
) -> None:
    resolve(data)


@EXAMPLES
@given(lattice_scenarios())
def test_any_lattice_world_and_signal_resolves_to_finite_physics_or_is_refused(
    data: dict[str, Any],
) -> None:
    resolve(data)


TUMOUR_SIGNAL = {"preset": "tumour-microswimmers", "communication": {"model": "attractant"}}
# A scenario, a section of it, and the numeric fields of the section that take extreme values
# one at a time (each physics' own signal rates).
EXTREME_CASES = [
    ({"preset": "tumour-nanorobots"}, "physics", ("model",)),
    ({"physics": {"model": "active_brownian", "time_limit_s": 1.0}}, "physics", ("model",)),
    (TUMOUR_SIGNAL, "communication", ("model", *LATTICE_SIGNAL)),
    *(
        ({"preset": "diffuse-tumour", "communication": {"model": model}}, "communication",
         ("model", *BROWNIAN_SIGNAL))
        for model in ("attractant_repellent", "broadcast")
    ),
    *(
        ({"preset": "diffuse-tumour"}, part, ())
        for part in ("space", "cells", "obstacles", "robots")
    ),
    *(({"biomarker": {"model": model}}, "biomarker", ("model",)) for model in MODEL_CODES),
]  # fmt: skip


def _numeric(part: str, leave_out: tuple[str, ...]) -> list[str]:
    """The fields of a section that hold a number (or null), but those left out."""
    properties = DEFS[part.capitalize()]["properties"]
    return [
        name
        for name, spec in sorted(properties.items())
        if name not in leave_out
        and {"number", "integer"} & {b.get("type") for b in spec.get("anyOf", [spec])}
    ]


@EXAMPLES
@given(
    case=st.sampled_from(EXTREME_CASES),
    data=st.data(),
    value=st.sampled_from([*EXTREMES, *(-v for v in EXTREMES), 0.0]),
)
def test_an_extreme_value_of_any_field_resolves_or_is_refused_naming_it(
    case: tuple[dict[str, Any], str, tuple[str, ...]], data: st.DataObject, value: float
) -> None:
    base, part, leave_out = case
    name = data.draw(st.sampled_from(_numeric(part, leave_out)))
    sent = {**base, part: {**base.get(part, {}), name: value}}
    at = (part, name)
    try:
        s = Scenario.model_validate(sent)
    except ValidationError as error:
        for e in error.errors():
            loc = tuple(e["loc"])
            assert loc == at or (e["type"] == "scenario_rule" and loc not in DERIVED), (sent, e)
        event("refused")
        return
    event("resolved")
    assert_physical(s)
