"""The work a scenario may ask for, checked before it is queued, alone or in a study."""

from __future__ import annotations

from collections.abc import Sequence

from nanonav.scenario import Scenario
from nanonav.settings import Settings
from service.problems import BudgetExceeded, FieldError, field_error

BUDGET_FIELDS = (("robots", "count"), ("learning", "max_steps"), ("learning", "episodes"))


def over_budget(scenario: Scenario, settings: Settings) -> str | None:
    """Why ``scenario`` costs more than the settings allow, or None if it fits."""
    if scenario.robot_steps_budget > settings.robot_steps_budget:
        return (
            f"robots.count x learning.max_steps x (learning.episodes + 1) = "
            f"{scenario.robot_steps_budget} robot-steps, over the budget of "
            f"{settings.robot_steps_budget}"
        )
    return None


def check_budget(
    scenario: Scenario, settings: Settings, blame: Sequence[Sequence[str | int]] | None = None
) -> None:
    """Refuse ``scenario`` with 422 if it is over budget, naming the fields in ``blame`` (by
    default those of the scenario that set its cost)."""
    detail = over_budget(scenario, settings)
    if detail is None:
        return
    where = blame if blame is not None else [("body", *loc) for loc in BUDGET_FIELDS]
    errors: list[FieldError] = [field_error(loc, detail, "budget_exceeded") for loc in where]
    raise BudgetExceeded(detail, errors)
