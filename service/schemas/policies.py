"""Policies: the body of ``POST /policies`` and a policy as the API answers it."""

from __future__ import annotations

from datetime import datetime
from typing import Annotated, Any, Literal

from pydantic import (
    Base64Bytes,
    BaseModel,
    ConfigDict,
    Field,
    ValidationError,
    ValidatorFunctionWrapHandler,
    field_validator,
)
from pydantic_core import ErrorDetails, PydanticCustomError

from nanonav.engine import qlearning
from nanonav.engine.observations import OBSERVATION_LABELS
from nanonav.policy import MAX_ACTIONS, MAX_Q, MAX_STATES, MAX_TABLES, UNVISITED
from nanonav.scenario import ActionSet, CommunicationModel
from nanonav.store import PolicyRecord
from service.paging import CURSOR_PATTERN
from service.schemas.results import GreedyState

MAX_LABEL = 200
Label = Annotated[str, Field(min_length=1, max_length=MAX_LABEL)]
Row = Annotated[list[float], Field(min_length=1, max_length=MAX_ACTIONS)]
Table = Annotated[list[Row], Field(min_length=1, max_length=MAX_STATES)]
Tables = Annotated[list[Table], Field(min_length=1, max_length=MAX_TABLES)]

_BEHAVIOR_STATES, _BEHAVIOR_ACTIONS = qlearning.labels("behaviors")
NEW_POLICY_EXAMPLES: dict[str, Any] = {
    "greedy": {
        "summary": "A greedy table: an action per state",
        "value": {
            "name": "distilled from PPO",
            "states": _BEHAVIOR_STATES,
            "actions": _BEHAVIOR_ACTIONS,
            "greedy": [
                {"state": state, "action": _BEHAVIOR_ACTIONS[i % 2]}
                for i, state in enumerate(_BEHAVIOR_STATES)
            ],
        },
    },
    "values": {
        "summary": "Action values: a row per state, a column per action",
        "value": {
            "states": _BEHAVIOR_STATES,
            "actions": _BEHAVIOR_ACTIONS,
            "values": [[0.5, 1.0, -0.25, 0.0] for _ in _BEHAVIOR_STATES],
        },
    },
}


class GreedyChoice(BaseModel):
    """A state and the action a greedy robot takes in it, as ``GET /jobs/{id}/qtable`` lists
    them in ``greedy``; its other keys (value, visits, learned, ties, gap) are ignored."""

    model_config = ConfigDict(extra="ignore", strict=True)

    state: Label
    action: Label = Field(
        description=f"An action label, or '{UNVISITED}': no action is preferred in this state."
    )


class NewPolicy(BaseModel):
    """A Q-table or a network made elsewhere (say, by training on NanoNav's Gymnasium or
    PettingZoo environments), for scenarios to evaluate.

    A table: ``states`` and ``actions`` are the labels of its rows and columns, in order:
    exactly those the engine has for one action set and communication model (an environment's
    ``state_labels`` and ``action_labels``). The table is ``values`` or ``greedy``, exactly
    one of them.

    A network: ``onnx``, an ONNX model in base64, that takes a float32 batch of observations
    (batch x the columns ``observation`` names, an environment's ``observation_labels``) and
    gives the logits of ``actions`` (batch x actions) or the action numbers (batch);
    ``observation`` and ``actions`` may be left out when the model's metadata names them
    (``nanonav train`` writes them)."""

    model_config = ConfigDict(
        extra="forbid",
        strict=True,
        json_schema_extra={"examples": [NEW_POLICY_EXAMPLES["greedy"]["value"]]},
    )

    name: str | None = Field(None, max_length=200, description="What to call it in lists.")
    states: list[Label] | None = Field(
        None,
        min_length=1,
        max_length=MAX_STATES,
        description="A table's: the state of each row, in order.",
    )
    actions: list[Label] | None = Field(
        None,
        min_length=1,
        max_length=MAX_ACTIONS,
        description="The action of each column of a table, or of each logit of a network, in "
        "order (for a network, the model's metadata may name them instead).",
    )
    observation: list[Label] | None = Field(
        None,
        min_length=1,
        max_length=len(OBSERVATION_LABELS),
        description="A network's: the observation column of each input, in order (an "
        "environment's observation_labels; the model's metadata may name them instead).",
    )
    onnx: Base64Bytes | None = Field(
        None,
        strict=False,  # base64 text decodes to the model's bytes
        description="A network: the ONNX model's bytes in base64 (at most "
        "NANONAV_POLICY_MODEL_MAX_BYTES decoded). It is checked before it is kept: one float32 "
        "input (batch x observation), a first output of logits (batch x actions) or actions "
        "(batch), the standard operator sets only, weights inside the model, no loops, every "
        "computed value of a fixed size per observation, and one trial run.",
    )
    values: Table | Tables | None = Field(
        None,
        description="Action values, [state][action] for a table every robot starts from, or "
        f"[robot][state][action] for one per robot (at most {MAX_TABLES}); finite numbers "
        f"within +-{MAX_Q:g}, far beyond what any job learns.",
    )
    greedy: list[GreedyChoice] | None = Field(
        None,
        max_length=MAX_STATES,
        description="Instead of values: the greedy action of each state, each state at most "
        "once; it becomes a table of 1.0 for that action and 0 for the others, a row of zeros "
        f"for a state left out or '{UNVISITED}'.",
    )

    @field_validator("values", mode="wrap")
    @classmethod
    def _a_table(cls, value: Any, handler: ValidatorFunctionWrapHandler) -> Any:
        """One error at ``values``: an error of each nesting it could have would point inside
        a schema's alternatives, not inside the body."""
        try:
            return handler(value)
        except ValidationError as error:
            # each error's location starts with its alternative: the one of the value's depth
            alternatives: dict[str | int, list[ErrorDetails]] = {}
            for found in error.errors(include_url=False):
                alternatives.setdefault(found["loc"][0], []).append(found)
            errors = list(alternatives.values())
            first = errors[-1 if _three_deep(value) else 0][0]
            where = "".join(f"[{part}]" for part in first["loc"][1:])
            raise PydanticCustomError(
                "table",
                "values must be a table of numbers, states x actions, or robots x states x "
                "actions: at values{where}, {reason}",
                {"where": where, "reason": first["msg"][:1].lower() + first["msg"][1:]},
            ) from None


def _three_deep(value: Any) -> bool:
    """Whether ``value`` starts as robots x states x actions would: a list of lists of lists."""
    for _ in range(3):
        if not isinstance(value, list) or not value:
            return False
        value = value[0]
    return True


class PolicyLinks(BaseModel):
    model_config = ConfigDict(populate_by_name=True)

    self_: str = Field(alias="self")


POLICY_EXAMPLE: dict[str, Any] = {
    "id": 3,
    "policy_from": "policy-3",
    "name": "distilled from PPO",
    "action_set": "behaviors",
    "communication": ["none"],
    "state_count": 72,
    "action_count": 4,
    "table_count": 1,
    "per_robot": False,
    "kind": "table",
    "created_at": "2026-12-03T10:00:00Z",
    "links": {"self": "/policies/3"},
}


class PolicySummary(BaseModel):
    """A policy as lists show it and ``POST /policies`` answers."""

    model_config = ConfigDict(json_schema_extra={"examples": [POLICY_EXAMPLE]})

    id: int
    policy_from: str = Field(description="What a scenario's policy_from names it by.")
    name: str | None
    action_set: ActionSet = Field(description="The learning.actions its table is for.")
    communication: list[CommunicationModel] = Field(
        description="The communication.model values whose states are its rows (the attractant "
        "models sense the same states; 'directions' is used without communication)."
    )
    state_count: int
    action_count: int
    table_count: int = Field(
        description="1 for a table every robot starts from; else one table per robot, and a "
        "scenario that evaluates it needs as many robots, each learning its own."
    )
    per_robot: bool = Field(description="Whether values is [robot][state][action].")
    kind: Literal["table", "network"] = Field(
        description="'table': a Q-table; 'network': an ONNX model (its state_count is the "
        "width of its observation)."
    )
    created_at: datetime
    links: PolicyLinks

    @classmethod
    def fields_of(cls, record: PolicyRecord) -> dict[str, Any]:
        return {
            "id": record.id,
            "policy_from": record.policy_from,
            "name": record.name,
            "action_set": record.action_set,
            "communication": list(record.communication),
            "state_count": record.states,
            "action_count": record.actions,
            "table_count": record.tables,
            "per_robot": record.per_robot,
            "kind": record.kind,
            "created_at": record.created_at,
            "links": PolicyLinks(self_=f"/policies/{record.id}"),
        }

    @classmethod
    def of(cls, record: PolicyRecord) -> PolicySummary:
        return cls(**cls.fields_of(record))


class Policy(PolicySummary):
    """A policy with its table (labels, values and the greedy action of every state), or a
    network with what it reads and chooses."""

    states: list[str] | None = Field(None, description="A table's rows.")
    actions: list[str]
    values: list[Any] | None = Field(
        None, description="A table's: [state][action], or [robot][state][action]."
    )
    greedy: list[GreedyState] | None = Field(
        None,
        description="A table's: a row per state, as GET /jobs/{id}/qtable gives it (visits are "
        "0: nothing was visited here); for per-robot tables, the greedy table of their plain "
        "mean.",
    )
    observation: list[str] | None = Field(
        None, description="A network's: the observation column of each input."
    )
    model_bytes: int | None = Field(None, description="A network's: its ONNX model's size.")
    memory: int | None = Field(
        None,
        description="A network's: the memory inputs it carries from decision to decision (a "
        "recurrent one's; 0 for none).",
    )
    multiply_adds: int | None = Field(
        None,
        description="A network's: the multiply-adds one observation costs, counted from its "
        "graph when it was sent (what a job's work budget charges for each decision).",
    )
    live_bytes: int | None = Field(
        None,
        description="A network's: the most memory its values hold at once for one "
        "observation, counted from its graph when it was sent.",
    )


class PolicyPage(BaseModel):
    """A page of policies, newest first."""

    policies: list[PolicySummary]
    next_cursor: str | None = Field(
        pattern=CURSOR_PATTERN, description="Pass as ?cursor= for the next page; null at the end."
    )
    next: str | None = Field(description="The next page's URL, or null.")
