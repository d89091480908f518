"""A study: one base scenario, a grid of values for some of its fields, and a list of seeds.

Every grid point (one value per grid key) runs once per seed, and every point uses the same
seeds, so methods compared across points face the same worlds and can be paired seed by seed.
``expand`` validates every point as a scenario before anything runs: a point that is not a
valid scenario is reported against the grid key and the value at fault.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass
from typing import Annotated, Any

from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    PlainValidator,
    ValidationError,
    WithJsonSchema,
    model_validator,
)
from pydantic_core import InitErrorDetails, PydanticCustomError

from nanonav.scenario import MAX_EXACT_INT, Scenario, whole

GridValue = bool | int | float | str | None


def _scalar(value: Any) -> GridValue:
    """One error for any value that is not a JSON scalar (not one per union member). null is
    one: a field whose default is null (``cells.capacity``) is swept through it."""
    if value is None or isinstance(value, bool | int | str):
        return value
    if isinstance(value, float) and math.isfinite(value):
        return value
    raise ValueError("a grid value is a finite number, a string, true, false or null")


GridValueField = Annotated[
    GridValue,
    PlainValidator(_scalar),
    WithJsonSchema(
        {"anyOf": [{"type": "number"}, {"type": "string"}, {"type": "boolean"}, {"type": "null"}]}
    ),
]
MAX_GRID_VALUES = 100
MAX_SEEDS = 10_000


def grid_keys() -> dict[str, type[BaseModel] | None]:
    """Every scenario field a grid may sweep, by dotted name (``robots.policy``); ``seed`` is
    not one of them: the study's seeds are."""
    keys: dict[str, type[BaseModel] | None] = {}
    for name, field in Scenario.model_fields.items():
        part = field.annotation
        if isinstance(part, type) and issubclass(part, BaseModel):
            keys.update({f"{name}.{inner}": part for inner in part.model_fields})
        elif name != "seed":
            keys[name] = None
    return keys


GRID_KEYS = grid_keys()


def _value_schema(key: str) -> dict[str, Any]:
    """The JSON Schema of one grid key's values: its scenario field's type and bounds, null
    among them where the field takes null."""
    model = GRID_KEYS[key] or Scenario
    field = model.model_json_schema()["properties"][key.rpartition(".")[2]]
    return {k: v for k, v in field.items() if k not in ("title", "description", "default")}


def _grid_schema() -> dict[str, Any]:
    """What the OpenAPI document says of ``grid``: its keys, and each key's values."""
    values = {"type": "array", "minItems": 1, "maxItems": MAX_GRID_VALUES, "uniqueItems": True}
    return {
        "propertyNames": {"enum": list(GRID_KEYS)},
        "properties": {key: {**values, "items": _value_schema(key)} for key in GRID_KEYS},
    }


Seed = Annotated[int, Field(ge=0, le=MAX_EXACT_INT)]
# JSON Schema's uniqueItems, as JSON compares: 1 and 1.0 are one value, 1 and true are two.
GridValues = Annotated[
    list[GridValueField],
    Field(min_length=1, max_length=MAX_GRID_VALUES, json_schema_extra={"uniqueItems": True}),
]


def _same(a: GridValue, b: GridValue) -> bool:
    return isinstance(a, bool) == isinstance(b, bool) and a == b


def grid_index(spec: StudySpec, key: str, value: GridValue) -> int:
    """Where ``value`` is listed under ``key``: true is not 1 here, as in JSON."""
    return next(i for i, listed in enumerate(spec.grid[key]) if _same(listed, value))


def _error(loc: tuple[str | int, ...], value: Any, message: str) -> ValidationError:
    error = PydanticCustomError("study_rule", message)
    return ValidationError.from_exception_data(
        "StudySpec", [InitErrorDetails(type=error, loc=loc, input=value)]
    )


class StudySpec(BaseModel):
    """What a client asks for: ``base`` x ``grid`` x seeds, and which grid key to compare."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False, strict=True)

    @model_validator(mode="before")
    @classmethod
    def _whole_numbers(cls, data: Any) -> Any:
        """5.0 is the integer 5, as in a scenario."""
        if not isinstance(data, dict):
            return data
        fixed = dict(data)
        if "replicates" in fixed:
            fixed["replicates"] = whole(fixed["replicates"])
        if isinstance(fixed.get("seeds"), list):
            fixed["seeds"] = [whole(seed) for seed in fixed["seeds"]]
        return fixed

    name: str = Field("", max_length=200, description="A name to recognise the study by.")
    base: dict[str, Any] = Field(
        default_factory=dict,
        description="The scenario every grid point starts from (as in POST /jobs; a preset "
        "applies). Its seed is ignored: the study's seeds replace it.",
    )
    grid: dict[str, GridValues] = Field(
        default_factory=dict,
        max_length=8,
        json_schema_extra=_grid_schema(),
        description="Scenario fields to sweep, by dotted name, each with the values to try, "
        "e.g. {'robots.policy': ['q_learning', 'gradient'], 'obstacles.count': [0, 10, 30]}. "
        "Every combination is a grid point, and must be a valid scenario (422 naming the grid "
        "value otherwise): each value of the field's type and bounds in POST /jobs, and the "
        "scenario's rules across fields hold at every point.",
    )
    seeds: list[Seed] | None = Field(
        None,
        min_length=1,
        max_length=MAX_SEEDS,
        json_schema_extra={"uniqueItems": True},
        description="The seeds every grid point runs with, each once. Give exactly one of "
        "'seeds' and 'replicates' (422 otherwise).",
    )
    replicates: int | None = Field(
        None,
        ge=1,
        le=MAX_SEEDS,
        description="Run every grid point with seeds 0 .. replicates-1 (or give 'seeds').",
    )
    compare: str | None = Field(
        None,
        description="A grid key whose values are compared pairwise, seed by seed: each value "
        "against the first one listed, at every combination of the other grid keys. It must "
        "be a key of 'grid', with two values or more.",
    )

    @model_validator(mode="after")
    def _coherent(self) -> StudySpec:
        if (self.seeds is None) == (self.replicates is None):
            raise _error(("seeds",), self.seeds, "give either 'seeds' or 'replicates'")
        if self.seeds is not None and len(set(self.seeds)) != len(self.seeds):
            raise _error(("seeds",), self.seeds, "seeds must not repeat")
        for key, values in self.grid.items():
            if key not in GRID_KEYS:
                raise _error(
                    ("grid", key),
                    key,
                    "not a scenario field that a grid can sweep; those are " + ", ".join(GRID_KEYS),
                )
            if not 1 <= len(values) <= MAX_GRID_VALUES:
                raise _error(("grid", key), values, f"give between 1 and {MAX_GRID_VALUES} values")
            for i, value in enumerate(values):
                if any(_same(value, seen) for seen in values[:i]):
                    raise _error(("grid", key, i), value, "this value is already listed")
        if self.compare is not None:
            if self.compare not in self.grid:
                raise _error(("compare",), self.compare, "must be one of the grid's keys")
            if len(self.grid[self.compare]) < 2:
                raise _error(
                    ("grid", self.compare), self.grid[self.compare], "compare needs two values"
                )
        return self

    @property
    def seed_list(self) -> list[int]:
        if self.seeds is not None:
            return list(self.seeds)
        return list(range(self.replicates or 0))

    @property
    def job_count(self) -> int:
        points = 1
        for values in self.grid.values():
            points *= len(values)
        return points * len(self.seed_list)


@dataclass(frozen=True)
class GridPoint:
    """One combination of grid values and its scenario (seed still to be set)."""

    index: int
    values: dict[str, GridValue]
    scenario: Scenario

    def with_seed(self, seed: int) -> Scenario:
        return self.scenario.model_copy(update={"seed": seed})


def point_values(spec: StudySpec) -> list[dict[str, GridValue]]:
    """The grid values of every point, in point order (the last key varies fastest)."""
    keys = list(spec.grid)
    return [
        dict(zip(keys, combination, strict=True))
        for combination in itertools.product(*(spec.grid[k] for k in keys))
    ]


def points(spec: StudySpec) -> list[GridPoint]:
    """Every grid point, in order (the last key varies fastest), validated as a scenario.

    Raises ``ValidationError`` located at ``base`` for a base that is not a scenario, and at
    ``grid/<key>/<index>`` for the first value that makes a point invalid."""
    try:
        Scenario.model_validate(spec.base)
    except ValidationError as error:
        first = error.errors(include_url=False)[0]
        raise _error(("base", *first["loc"]), first.get("input"), first["msg"]) from None
    found: list[GridPoint] = []
    for index, values in enumerate(point_values(spec)):
        data = _with_values(spec.base, values)
        try:
            scenario = Scenario.model_validate(data)
        except ValidationError as error:
            raise _point_error(spec, values, error) from None
        found.append(GridPoint(index, values, scenario))
    return found


def _with_values(base: dict[str, Any], values: dict[str, GridValue]) -> dict[str, Any]:
    data: dict[str, Any] = {k: (dict(v) if isinstance(v, dict) else v) for k, v in base.items()}
    for key, value in values.items():
        part, _, field = key.partition(".")
        if field:
            inner = data.get(part)
            data[part] = {**(inner if isinstance(inner, dict) else {}), field: value}
        else:
            data[part] = value
    return data


def _point_error(
    spec: StudySpec, values: dict[str, GridValue], error: ValidationError
) -> ValidationError:
    """The first error of a grid point, placed on the grid value that caused it: the key the
    error names, or else (a rule that spans fields) the first key of the point."""
    first = error.errors(include_url=False)[0]
    where = ".".join(str(part) for part in first["loc"])
    key = next((k for k in values if where == k or where.startswith(k + ".")), next(iter(values)))
    value = values[key]
    point = ", ".join(f"{k}={v!r}" for k, v in values.items())
    message = f"at the grid point {point}: {where or 'scenario'}: {first['msg']}"
    return _error(("grid", key, grid_index(spec, key, value)), value, message)
