"""The table a scenario names (``policy_from``: a job's learned one, or a policy's), checked
before it is queued, alone or in a study."""

from __future__ import annotations

from collections.abc import Callable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from typing import Any, cast

from numpy.typing import NDArray

from nanonav.policy import Network, TableReader, UnusablePolicy, learned_policy, steering_of
from nanonav.rl.graph import InvalidModel
from nanonav.rl.onnx_policy import Limits, check_model
from nanonav.scenario import Scenario
from nanonav.settings import Settings
from nanonav.store import PolicyNotFound
from service.problems import InvalidInput, field_error

# ``security.owned_tables`` declares a job's id, and reads a policy's name as well: it passes
# either to ``JobStore.owner_of`` and ``JobStore.qtable``, which take both.
JobTableReader = Callable[[int], Mapping[str, NDArray[Any]]]


def check_policy_from(
    scenario: Scenario,
    read: JobTableReader,
    loc: Sequence[str | int],
    where: str = "",
    *,
    settings: Settings,
    counted: dict[bytes, int] | None = None,
) -> int | None:
    """Refuse ``scenario`` with 422 at ``loc`` when its ``policy_from`` names no job or policy
    whose table or network it can evaluate; ``where`` says which grid point, in a study.

    Returns the multiply-adds an observation of the network it names (None for a table, or
    none), for the budget: as its check counted them, or for a network kept before costs were
    counted, as they are counted now, in its sandbox (and remembered in ``counted``, by
    model, for the other points of a study)."""
    if scenario.policy_from is None:
        return None
    try:
        policy = learned_policy(scenario, cast(TableReader, read))
    except UnusablePolicy as error:
        raise _unusable(loc, f"{where}{error}") from None
    if not isinstance(policy, Network):
        return None
    if policy.multiply_adds is not None:
        return policy.multiply_adds
    counted = {} if counted is None else counted
    if policy.model not in counted:
        try:
            info = check_model(
                policy.model, len(policy.observation), len(policy.actions),
                max_bytes=settings.policy_model_max_bytes,
                continuous=steering_of(policy.actions) == "continuous",
                limits=Limits.of(settings),
            )  # fmt: skip
        except InvalidModel as error:
            raise _unusable(loc, f"{where}{scenario.policy_from}: {error}") from None
        counted[policy.model] = info.cost.multiply_adds
    return counted[policy.model]


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
