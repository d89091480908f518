"""The table a scenario names (``policy_from``: a job's learned one, or a policy's), checked
before it is queued, alone or in a study."""

from __future__ import annotations

from collections.abc import Callable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from typing import Any, cast

from numpy.typing import NDArray

from nanonav.policy import TableReader, UnusablePolicy, learned_policy
from nanonav.scenario import Scenario
from nanonav.store import PolicyNotFound
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
        learned_policy(scenario, cast(TableReader, read))
    except UnusablePolicy as error:
        raise _unusable(loc, f"{where}{error}") from None


@contextmanager
def policies_kept(blame: Callable[[int], tuple[Sequence[str | int], str]]) -> Iterator[None]:
    """Refuse, as the check does, jobs whose policy was deleted after the check and before
    they were queued (the store queues none then); ``blame`` says where a policy's id was
    named, and which grid point it is."""
    try:
        yield
    except PolicyNotFound as error:
        loc, where = blame(error.policy_id)
        raise _unusable(loc, f"{where}{error}") from None


def _unusable(loc: Sequence[str | int], reason: str) -> InvalidInput:
    problem = field_error(loc, reason, "policy_unusable")
    return InvalidInput(f"{problem.pointer}: {problem.detail}", [problem])
