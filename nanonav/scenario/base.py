"""What every part of a scenario is built on: strict parts (``Part``), the error of a rule
that spans fields, and whether a value is one a field takes."""

from __future__ import annotations

import math
import operator
from typing import Any, get_args

from pydantic import (
    BaseModel,
    ConfigDict,
    ValidationError,
    model_validator,
)
from pydantic_core import InitErrorDetails, PydanticCustomError


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


def field_error(model: str, loc: tuple[str, ...], value: Any, message: str) -> ValidationError:
    """A validation error that names the field at fault, for rules that span several fields."""
    error = PydanticCustomError("scenario_rule", message)
    return ValidationError.from_exception_data(
        model, [InitErrorDetails(type=error, loc=loc, input=value)]
    )


class Part(BaseModel):
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


# The bounds a field's metadata may hold (annotated_types' Gt, Ge, Lt and Le), by attribute.
_BOUNDS = (("gt", operator.gt), ("ge", operator.ge), ("lt", operator.lt), ("le", operator.le))


def admits(model: type[BaseModel], name: str, value: Any) -> bool:
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
