"""Policies: Q-tables made elsewhere and sent, for scenarios to evaluate as ``policy-<id>``."""

from __future__ import annotations

from typing import Annotated, Any

import numpy as np
from fastapi import APIRouter, Body, Query, Request, Response
from fastapi.concurrency import run_in_threadpool
from numpy.typing import NDArray

from nanonav.policy import (
    LAYOUT_RULE,
    TABLE_RULE,
    InvalidPolicy,
    Layout,
    NetworkLayout,
    greedy_table,
    greedy_values,
    layout_of,
    network_layout,
    policy_values,
    steering_of,
)
from nanonav.rl.graph import RULE as MODEL_RULE
from nanonav.rl.graph import InvalidModel, ModelInfo
from nanonav.rl.onnx_policy import Limits, ModelCheck
from nanonav.store import PolicyRecord
from service.deps import JsonBody, SettingsDep, StoreDep
from service.idempotency import IdempotencyDep
from service.ids import PolicyId
from service.paging import Cursor, decode_cursor, encode_cursor
from service.problems import (
    PROBLEM_BASE,
    InvalidInput,
    Problem,
    field_error,
    problem_response,
    problems,
)
from service.schemas import (
    NEW_POLICY_EXAMPLES,
    GreedyState,
    NewPolicy,
    Policy,
    PolicyPage,
    PolicySummary,
)
from service.security import SCRIPTED_ONLY, CallerDep
from service.uploads import NetworkChecks

router = APIRouter(prefix="/policies", tags=["policies"])
# The rule a body breaks that mixes a table's fields and a network's
KIND = "policy_kind"


@router.post(
    "",
    status_code=201,
    response_model=PolicySummary,
    dependencies=[JsonBody],
    responses=problems(400, 403, 409, 413, 415, 422, 503),
)
async def send_policy(
    policy: Annotated[NewPolicy, Body(openapi_examples=NEW_POLICY_EXAMPLES)],
    request: Request,
    store: StoreDep,
    settings: SettingsDep,
    caller: CallerDep,
    response: Response,
    idempotency: IdempotencyDep,
) -> PolicySummary:
    """Keep a Q-table or a network (an ONNX model) made elsewhere; a scenario evaluates it as
    ``policy_from: "policy-<id>"``.

    A body the schema allows may still be refused with 422, each error typed by its rule:
    ``policy_layout`` (``states`` or ``actions`` that are not, in order, the labels of one of
    the engine's action sets and communication models; a network's ``observation`` that is
    no robot's, or ``actions`` and ``observation`` that no scenario gives together; the
    detail says which would be), ``policy_model`` (a network the service cannot run: not
    ONNX, too large, external data, other operator sets, an input or output of the wrong
    shape or type, values of no fixed size, or a failing trial run; the detail says which),
    ``policy_kind`` (a table's fields and a network's mixed), ``base64_decode`` (``onnx``
    that is not base64),
    ``policy_table`` (both or neither of ``values`` and ``greedy``; values not shaped states x
    actions, or not finite numbers within +-1e30; a greedy state or action the layout does not
    have, or a state given twice), ``idempotency_key``, ``idempotency_key_reused`` and
    ``nul_character`` (U+0000 in any string of the body, key or value, or in the key: the
    store cannot keep it). A key that keeps ``NANONAV_QUOTA_POLICIES`` policies already gets
    409 ``policy-limit``. Networks are checked a few at a time in each API process, a few
    more wait their turn, and past them a request gets 503 ``checks-busy`` with Retry-After
    at once (``NANONAV_NETWORK_CHECKS_AT_ONCE``, ``NANONAV_NETWORK_CHECKS_WAITING``)."""
    if policy.onnx is not None:
        model = policy.onnx
        checks: NetworkChecks = request.app.state.network_checks
        _network_fields(policy)
        async with checks.turn():
            layout, info = await run_in_threadpool(_checked_network, policy, model, settings)
        record = await run_in_threadpool(
            store.policies.add_network,
            action_set=layout.actions,
            communication=layout.communication,
            observation=list(layout.observation),
            actions=list(layout.action_labels),
            model=model,
            memory=len(info.memory),
            cost=info.cost.to_dict(),
            name=policy.name,
            owner=caller.owner,
            idempotency=idempotency,
            limit=settings.quota_policies,
        )
    else:
        record = await run_in_threadpool(_keep_table, policy, store, settings, caller, idempotency)
    response.headers["Location"] = f"/policies/{record.id}"
    return PolicySummary.of(record)


def _keep_table(
    policy: NewPolicy,
    store: StoreDep,
    settings: SettingsDep,
    caller: CallerDep,
    idempotency: IdempotencyDep,
) -> PolicyRecord:
    try:
        layout = layout_of(_given(policy.states, "states"), _given(policy.actions, "actions"))
        if policy.observation is not None:
            raise InvalidPolicy(("observation",), "a table has states, not an observation", KIND)
        values = _values(policy, layout)
    except InvalidPolicy as error:
        raise _refused(error) from None
    return store.policies.add(
        action_set=layout.actions,
        communication=layout.communication,
        states=list(layout.state_labels),
        actions=list(layout.action_labels),
        values=values,
        name=policy.name,
        owner=caller.owner,
        idempotency=idempotency,
        limit=settings.quota_policies,
    )


def _refused(error: InvalidPolicy | InvalidModel, loc: tuple[str, ...] = ()) -> InvalidInput:
    """A 422 at the field ``error`` names (or at ``loc``)."""
    where = loc or (error.loc if isinstance(error, InvalidPolicy) else ())
    rule = error.rule if isinstance(error, InvalidPolicy) else MODEL_RULE
    problem = field_error(["body", *where], str(error), rule)
    return InvalidInput(f"{problem.pointer}: {problem.detail}", [problem])


def _given(labels: list[str] | None, field: str) -> list[str]:
    if labels is None:
        detail = f"a table needs {field} (a network is sent as onnx)"
        raise InvalidPolicy((field,), detail, KIND)
    return labels


def _network_fields(policy: NewPolicy) -> None:
    """Refuse a table's fields beside a network's model."""
    for field in ("states", "values", "greedy"):
        if getattr(policy, field) is not None:
            detail = f"a network is sent as onnx, observation and actions; {field} is a table's"
            raise _refused(InvalidPolicy((field,), detail, KIND))


def _checked_network(
    policy: NewPolicy, model: bytes, settings: SettingsDep
) -> tuple[NetworkLayout, ModelInfo]:
    """A network's layout (its labels, given or its metadata's) and what its check found, both
    read in one sandboxed process: the API never parses a model."""
    limit = settings.policy_model_max_bytes
    try:
        with ModelCheck(model, max_bytes=limit, limits=Limits.of(settings)) as check:
            named = check.labels()
            observation = policy.observation or named[0]
            actions = policy.actions or named[1]
            for labels, field in ((observation, "observation"), (actions, "actions")):
                if labels is None:
                    detail = f"a network needs {field}: the model's metadata names none"
                    raise InvalidPolicy((field,), detail, LAYOUT_RULE)
            assert observation is not None and actions is not None
            layout = network_layout(observation, actions)
            info = check.check(
                len(observation), len(actions), continuous=steering_of(actions) == "continuous"
            )
    except InvalidPolicy as error:
        raise _refused(error) from None
    except InvalidModel as error:
        raise _refused(error, ("onnx",)) from None
    return layout, info


def _values(policy: NewPolicy, layout: Layout) -> NDArray[np.float64]:
    if policy.values is not None and policy.greedy is None:
        return policy_values(layout, policy.values)
    if policy.greedy is not None and policy.values is None:
        return greedy_values(layout, [(choice.state, choice.action) for choice in policy.greedy])
    detail = "give exactly one of values and greedy, not " + (
        "neither" if policy.values is None else "both"
    )
    errors = [field_error(["body", name], detail, TABLE_RULE) for name in ("values", "greedy")]
    raise InvalidInput(detail, errors)


@router.get("", response_model=PolicyPage, responses=problems(422))
def list_policies(
    store: StoreDep,
    caller: CallerDep,
    limit: Annotated[int, Query(ge=1, le=100, description="Policies per page.")] = 20,
    cursor: Cursor = None,
) -> PolicyPage:
    """A page of policies, newest first, without their tables; with API keys, the caller's."""
    before = None if cursor is None else decode_cursor(cursor)
    page = store.policies.page(limit=limit, before_id=before, owner=caller.only)
    next_cursor = None if page.next_before_id is None else encode_cursor(page.next_before_id)
    return PolicyPage(
        policies=[PolicySummary.of(record) for record in page.policies],
        next_cursor=next_cursor,
        next=None if next_cursor is None else f"/policies?limit={limit}&cursor={next_cursor}",
    )


@router.get("/{policy_id}", response_model=Policy, responses=problems(404, 422))
def get_policy(policy_id: PolicyId, store: StoreDep) -> Policy:
    """A policy with its table and the greedy action of every state, or a network with the
    labels of its observation and actions."""
    record = store.policies.get(policy_id)
    table = store.policies.table(policy_id)
    if "model" in table:
        return Policy(
            **PolicySummary.fields_of(record),
            actions=table["actions"].tolist(),
            observation=table["observation"].tolist(),
            model_bytes=int(table["model"].size),
            memory=int(table["memory"]) if "memory" in table else 0,
            multiply_adds=_counted(table, "multiply_adds"),
            live_bytes=_counted(table, "live_bytes"),
        )
    states, actions = table["states"].tolist(), table["actions"].tolist()
    values = table["values"]
    unvisited = np.zeros(values.shape, dtype=np.int64)
    greedy = greedy_table(states, actions, values, unvisited)
    return Policy(
        **PolicySummary.fields_of(record),
        states=states,
        actions=actions,
        values=values.tolist(),
        greedy=[GreedyState.model_validate(g.to_dict()) for g in greedy],
    )


def _counted(table: dict[str, NDArray[Any]], what: str) -> int | None:
    """What a network's check counted of its cost (None for one kept before costs were)."""
    found = table.get(f"cost_{what}")
    return None if found is None else int(found)


@router.get(
    "/{policy_id}/model",
    response_class=Response,
    responses={
        200: {"content": {"application/octet-stream": {}}, "description": "The ONNX model."},
        **problems(404, 422),
    },
)
def get_model(policy_id: PolicyId, store: StoreDep) -> Response:
    """A network's ONNX model, as it was sent (404 ``no-model`` for a table)."""
    table = store.policies.table(policy_id)
    if "model" not in table:
        problem = Problem(
            type=PROBLEM_BASE + "no-model",
            title="No model",
            status=404,
            detail=f"policy {policy_id} is a Q-table, not a network: GET /policies/{policy_id} "
            "has its values",
        )
        return problem_response(problem)
    return Response(
        table["model"].tobytes(),
        media_type="application/octet-stream",
        headers={"Content-Disposition": f'attachment; filename="policy-{policy_id}.onnx"'},
    )


@router.delete(
    "/{policy_id}",
    status_code=204,
    response_class=Response,
    responses={204: {"description": "Deleted."}, **problems(403, 404, 409, 415, 422)},
    openapi_extra=SCRIPTED_ONLY,
)
def delete_policy(policy_id: PolicyId, store: StoreDep) -> Response:
    """Delete a policy; 409 ``policy-in-use`` while queued or running jobs evaluate it (the
    detail names them: cancel them or let them finish first)."""
    store.policies.delete(policy_id)
    return Response(status_code=204)


async def policy_not_found(request: Request, exc: Exception) -> Response:
    """A policy that is not there, or is another key's: 404, as a missing job is."""
    problem = Problem(
        type=PROBLEM_BASE + "policy-not-found",
        title="Policy not found",
        status=404,
        detail=str(exc),
        instance=request.url.path,
    )
    return problem_response(problem)
