"""Text a request stores is kept alike on SQLite and PostgreSQL, or refused alike: a string with
U+0000 (NUL), which PostgreSQL keeps nowhere (text or JSON, key or value), is 422
``nul_character`` naming where it is in both; every other character comes back as it was sent."""

from __future__ import annotations

import asyncio
import json
from typing import Any

import httpx
import numpy as np
import pytest

from nanonav.engine import qlearning
from nanonav.settings import Settings
from nanonav.webhooks import callback_target
from service.app import create_app
from tests.conftest import SCRIPTED, Api
from tests.service.test_api import assert_problem
from tests.service.test_callbacks import SECRET

STATES, ACTIONS = qlearning.labels("behaviors")
POLICY: dict[str, Any] = {"states": STATES, "actions": ACTIONS, "values": np.eye(72, 4).tolist()}
STUDY: dict[str, Any] = {
    "base": {"learning": {"episodes": 1, "max_steps": 20}},
    "grid": {"robots.count": [1, 2]},
    "seeds": [0],
}
HOOK = "https://hooks.example.org/done"
JSON = {"content-type": "application/json"}
# Names in other scripts, directions and planes, with marks, controls and noncharacters.
NAMES = [
    "café crème",
    "e\u0301t\u00e9",
    "🧫 nanobots 🦠",
    "שלום עולם",
    "مرحبا\u200f 42",
    "tab\there\nnewline\r",
    "\u0001\u001f\u007f\u0085",
    "\ufeffbom \uffff \U0010ffff",
    "\u00a0",
]


@pytest.fixture
def api_settings(database_url: str) -> Settings:
    return Settings(
        database_url=database_url,
        max_body_bytes=64 * 1024,
        webhook_hosts=("hooks.example.org",),
        webhook_secret=SECRET,
    )


def refused_at(api: Api, path: str, body: Any, **params: str) -> list[tuple[str | None, str]]:
    """The pointers (or parameters) and types of a 422's errors; nothing stored."""
    problem = assert_problem(api.client.post(path, json=body, params=params), 422)
    return [(e.get("pointer") or e.get("parameter"), e["type"]) for e in problem["errors"]]


def nothing_stored(api: Api) -> None:
    for path, key in (("/jobs", "jobs"), ("/studies", "studies"), ("/policies", "policies")):
        assert api.client.get(path).json()[key] == [], path


def test_a_name_holding_nul_is_422_and_nothing_is_stored(api: Api) -> None:
    for name in ("\u0000", "a\u0000b", "trailing\u0000"):
        problem = assert_problem(api.client.post("/policies", json={**POLICY, "name": name}), 422)
        assert problem["errors"] == [
            {
                "pointer": "#/name",
                "loc": ["body", "name"],
                "detail": "the string holds U+0000 (NUL), a character the store cannot keep",
                "type": "nul_character",
            }
        ]
        assert problem["detail"] == f"#/name: {problem['errors'][0]['detail']}"
        assert refused_at(api, "/studies", {**STUDY, "name": name}) == [("#/name", "nul_character")]
    # JSON may come in UTF-16 or UTF-32 as well
    for encoding in ("utf-16", "utf-32-le"):
        content = json.dumps({**STUDY, "name": "a\u0000"}).encode(encoding)
        response = api.client.post("/studies", content=content, headers=JSON)
        assert assert_problem(response, 422)["errors"][0]["type"] == "nul_character"
    nothing_stored(api)


def test_nul_anywhere_in_a_body_key_or_value_at_any_depth_is_422_naming_it(api: Api) -> None:
    greedy = [{"state": STATES[0], "action": "explore"}, {"state": "s\u0000", "action": "x"}]
    cases: list[tuple[str, Any, str]] = [
        ("/studies", {**STUDY, "base": {"learning": {"a\u0000": 1}}}, "#/base/learning/a\u0000"),
        ("/studies", {**STUDY, "grid": {"robots.\u0000count": [1]}}, "#/grid/robots.\u0000count"),
        ("/studies", {**STUDY, "grid": {"robots.policy": ["q\u0000"]}}, "#/grid/robots.policy/0"),
        ("/studies", {**STUDY, "compare": "\u0000"}, "#/compare"),
        ("/jobs", {"learning": {"actions": "behaviors\u0000"}}, "#/learning/actions"),
        ("/jobs", {"robots": {"count": 2}, "\u0000": {}}, "#/\u0000"),
        ("/jobs", {"policy_from": "policy-1\u0000"}, "#/policy_from"),
        ("/policies", {**POLICY, "values": None, "greedy": greedy}, "#/greedy/1/state"),
        ("/policies", {**POLICY, "states": [*STATES[:-1], "\u0000"]}, "#/states/71"),
        ("/policies", {**POLICY, "extra": {"deep": [[{"k": ["\u0000"]}]]}}, "#/extra/deep/0/0/k/0"),
    ]
    for path, body, pointer in cases:
        assert refused_at(api, path, body) == [(pointer, "nul_character")], (path, body)
    nothing_stored(api)


def test_a_query_parameter_or_idempotency_key_holding_nul_is_422(
    api: Api, api_settings: Settings
) -> None:
    bodies: tuple[tuple[str, dict[str, Any]], ...] = (
        ("/jobs", {}),
        ("/studies", STUDY),
        ("/policies", POLICY),
    )
    for path, body in bodies:
        assert refused_at(api, path, body, callback_url=f"{HOOK}?run=\u0000") == [
            ("callback_url", "nul_character")
        ]
    app = create_app(api_settings)  # no HTTP server passes NUL in a header; an ASGI client can

    async def keyed() -> list[httpx.Response]:
        transport = httpx.ASGITransport(app=app)
        async with httpx.AsyncClient(transport=transport, base_url="http://testserver") as client:
            key = {"Idempotency-Key": "k\u0000", **SCRIPTED}
            return [await client.post(path, json=body, headers=key) for path, body in bodies]

    try:
        for response in asyncio.run(keyed()):
            [error] = assert_problem(response, 422)["errors"]
            assert (error["loc"], error["type"]) == (["header", "idempotency-key"], "nul_character")
    finally:
        app.state.store.close()
    nothing_stored(api)
    # the routes that only read take typed parameters: NUL there is a 422 of their type
    for path in (
        "/jobs?status=queued%00",
        "/jobs?policy=q_learning%00",
        "/jobs?cursor=1%00",
        "/studies?cursor=%00",
        "/policies/1%00",
        "/jobs/%00/qtable",
    ):
        assert assert_problem(api.client.get(path), 422)["errors"], path


def test_every_other_character_is_stored_and_read_back_as_sent(
    api: Api, api_settings: Settings
) -> None:
    for name in NAMES:
        policy = api.client.post("/policies", json={**POLICY, "name": name})
        assert policy.status_code == 201, policy.text
        assert api.client.get(policy.json()["links"]["self"]).json()["name"] == name
        study = api.client.post("/studies", json={**STUDY, "name": name})
        assert study.status_code == 202, study.text
        shown = api.client.get(study.json()["links"]["self"]).json()
        assert (shown["name"], shown["spec"]["name"]) == (name, name)
    listed = api.client.get("/policies", params={"limit": 100}).json()["policies"]
    assert [p["name"] for p in listed] == NAMES[::-1]
    studies = api.client.get("/studies", params={"limit": 100}).json()["studies"]
    assert [s["name"] for s in studies] == NAMES[::-1]
    hook = f"{HOOK}/café/🧫?to=שלום"
    job = api.client.post("/jobs", json={}, params={"callback_url": hook})
    assert job.status_code == 202, job.text
    sent = str(callback_target(hook, api_settings.webhook_hosts))
    assert api.client.get(f"/jobs/{job.json()['id']}/callback").json()["url"] == sent
