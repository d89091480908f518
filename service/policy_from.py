"""The table a scenario names (``policy_from``: a job's learned one, or a policy's), checked
before it is queued, alone or in a study."""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import Any, cast

from numpy.typing import NDArray

from nanonav.policy import TableReader, UnusablePolicy, learned_table
from nanonav.scenario import Scenario
from service.problems import InvalidInput, field_error

# ``security.owned_tables`` declares a job's id, and reads a policy's name as well: it passes
# either to ``JobStore.owner_of`` and ``JobStore.qtable``, which take both.
JobTableReader = Callable[[int], Mapping[str, NDArray[Any]]]


def check_policy_from(
    scenario: Scenario, read: JobTableReader, loc: Sequence[str | int], where: str = ""
) -> None:
    """Refuse ``scenario`` with 422 at ``loc`` when its ``policy_from`` names no job or policy
    whose table it can evaluate; ``where`` says which grid point, in a study."""
    if scenario.policy_from is None:
        return
    try:
        learned_table(scenario, cast(TableReader, read))
    except UnusablePolicy as error:
        reason = f"{where}{error}"
        problem = field_error(loc, reason, "policy_unusable")
        raise InvalidInput(f"{problem.pointer}: {problem.detail}", [problem]) from None
