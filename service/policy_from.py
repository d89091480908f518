"""The learned table a scenario names (``policy_from``), checked before it is queued, alone or
in a study."""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import Any

from numpy.typing import NDArray

from nanonav.policy import UnusablePolicy, learned_table
from nanonav.scenario import Scenario
from service.problems import InvalidInput, field_error

TableReader = Callable[[int], Mapping[str, NDArray[Any]]]


def check_policy_from(
    scenario: Scenario, read: TableReader, loc: Sequence[str | int], where: str = ""
) -> None:
    """Refuse ``scenario`` with 422 at ``loc`` when its ``policy_from`` names no job whose table
    it can evaluate; ``where`` says which grid point, in a study."""
    if scenario.policy_from is None:
        return
    try:
        learned_table(scenario, read)
    except UnusablePolicy as error:
        reason = f"{where}{error}"
        problem = field_error(loc, reason, "policy_unusable")
        raise InvalidInput(f"{problem.pointer}: {reason}", [problem]) from None
