"""The work a scenario may ask for, checked before it is queued, alone or in a study: against
the server's budget for one job, and against the quota of the key that asks."""

from __future__ import annotations

from collections.abc import Sequence

from nanonav.scenario import Scenario
from nanonav.scenario.work import decision_work
from nanonav.settings import Settings
from nanonav.store.quotas import Quota
from service.problems import BudgetExceeded, FieldError, InvalidInput, field_error

STEPS_FIELDS = (
    ("robots", "count"),
    ("learning", "max_steps"),
    ("learning", "episodes"),
    ("evaluation", "worlds"),
)


def over_budget(
    scenario: Scenario, settings: Settings, multiply_adds: int | None = None
) -> str | None:
    """Why ``scenario`` costs more than the settings allow, or None if it fits; with a network
    deciding that takes ``multiply_adds`` an observation, its decisions count too."""
    if scenario.robot_steps_budget > settings.robot_steps_budget:
        return (
            f"robots.count x learning.max_steps x (learning.episodes + evaluation.worlds) = "
            f"{scenario.robot_steps_budget:,} robot-steps, over the budget of "
            f"{settings.robot_steps_budget:,}"
        )
    work = scenario.work
    deciding = 0 if multiply_adds is None else decision_work(scenario, multiply_adds)
    if work + deciding > settings.work_budget:
        network = (
            f" and {deciding:.3g} for the network's decisions ({multiply_adds:,} multiply-adds "
            "an observation)"
            if deciding
            else ""
        )
        return (
            f"the run would cost {work + deciding:.3g} work units: {work:.3g} for robot-steps "
            f"weighed by the {scenario.sources} field sources, {scenario.obstacles.count} "
            f"obstacles and {scenario.cells.count} cells each goes through{network}, over the "
            f"budget of {settings.work_budget:.3g}: fewer robots, steps, episodes, cells, "
            "emitters or obstacles fit"
            + (", or a smaller network, or decisions less often" if deciding else "")
        )
    return None


def cost_fields(scenario: Scenario) -> list[tuple[str, str]]:
    """The fields that set a scenario's cost, to name in a refusal."""
    fields = [*STEPS_FIELDS, ("cells", "count"), ("obstacles", "count")]
    if scenario.biomarker.model == "inverse_square":
        fields.append(("biomarker", "emitters_per_cell"))
    return fields


def check_budget(
    scenario: Scenario,
    settings: Settings,
    blame: Sequence[Sequence[str | int]] | None = None,
    multiply_adds: int | None = None,
) -> None:
    """Refuse ``scenario`` with 422 if it is over budget, naming the fields in ``blame`` (by
    default those of the scenario that set its cost); ``multiply_adds`` as ``over_budget``."""
    detail = over_budget(scenario, settings, multiply_adds)
    if detail is None:
        return
    if blame is None:
        loc: list[tuple[str, ...]] = list(
            STEPS_FIELDS if "robot-steps," in detail else cost_fields(scenario)
        )
        if multiply_adds is not None:
            loc.append(("policy_from",))
        blame = [("body", *field) for field in loc]
    where = blame
    errors: list[FieldError] = [field_error(loc, detail, "budget_exceeded") for loc in where]
    raise BudgetExceeded(detail, errors)


def check_quota_fits(
    quota: Quota, *, jobs: int, robot_steps: int, blame: Sequence[Sequence[str | int]]
) -> None:
    """Refuse with 422 a submit larger than its quota allows even when nothing else is active:
    a 429 would tell the client to retry, and no retry could ever succeed."""
    details = []
    if quota.active_jobs and jobs > quota.active_jobs:
        details.append(
            f"it makes {jobs:,} jobs and the active_jobs quota (NANONAV_QUOTA_ACTIVE_JOBS) "
            f"allows {quota.active_jobs:,} queued and running at once"
        )
    if quota.robot_steps and robot_steps > quota.robot_steps:
        details.append(
            f"it asks for {robot_steps:,} robot-steps and the robot_steps quota "
            f"(NANONAV_QUOTA_ROBOT_STEPS) allows {quota.robot_steps:,} queued and running"
        )
    if details:
        detail = "this submit can never fit its quota: " + "; ".join(details) + ": make it smaller"
        raise InvalidInput(detail, [field_error(loc, detail, "quota_never_fits") for loc in blame])
