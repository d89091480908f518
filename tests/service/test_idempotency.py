"""The Idempotency-Key header on POST /jobs: replays, conflicts, and keys that are not keys."""

from __future__ import annotations

import secrets
import time
from typing import Any

import httpx
import pytest

from nanonav.settings import Settings
from nanonav.store.migrate import upgrade
from service.app import create_app
from tests.conftest import Api, serve


@pytest.fixture
def api_settings(sqlite_url: str) -> Settings:
    return Settings(
        database_url=sqlite_url, webhook_hosts="hooks.test", webhook_secret=secrets.token_hex(24)
    )


def post(api: Api, body: Any, key: str | bytes, **params: str) -> httpx.Response:
    content = body if isinstance(body, bytes) else None
    # a bytes key is sent as given: httpx's annotations have no bytes value under a str name
    headers: dict[str, Any] = {"Idempotency-Key": key, "Content-Type": "application/json"}
    return api.client.post(
        "/jobs",
        json=None if content is not None else body,
        content=content,
        headers=headers,
        params=params,
    )


def problem_parameter(response: httpx.Response) -> str:
    assert response.status_code == 422, response.text
    assert response.headers["content-type"] == "application/problem+json"
    parameter: str = response.json()["errors"][0]["parameter"]
    return parameter


def test_the_same_request_again_gets_the_same_job(api: Api) -> None:
    first = post(api, {"seed": 1, "learning": {"episodes": 2}}, "k-1")
    assert first.status_code == 202
    # The same JSON, written another way, is the same request.
    again = post(api, b'{ "learning": {"episodes": 2},\n "seed": 1 }', "k-1")
    assert again.status_code == 202
    assert again.json()["id"] == first.json()["id"]


def test_an_empty_body_resolving_to_a_random_seed_still_replays(api: Api) -> None:
    first = post(api, {}, "defaults")
    again = post(api, {}, "defaults")
    assert again.json()["id"] == first.json()["id"]
    assert again.json()["scenario"]["seed"] == first.json()["scenario"]["seed"]


def test_another_body_under_the_key_is_422_naming_the_header(api: Api) -> None:
    first = post(api, {"seed": 1}, "k-1").json()
    refused = post(api, {"seed": 2}, "k-1")
    assert problem_parameter(refused) == "idempotency-key"
    assert f"job {first['id']}" in refused.json()["detail"]
    assert len(api.client.get("/jobs").json()["jobs"]) == 1


def test_another_callback_url_under_the_key_is_another_request(api: Api) -> None:
    post(api, {"seed": 1}, "k-1", callback_url="https://hooks.test/a")
    refused = post(api, {"seed": 1}, "k-1", callback_url="https://hooks.test/b")
    assert problem_parameter(refused) == "idempotency-key"


@pytest.mark.parametrize("key", ["", "\u00a0\u3000".encode()])  # HTTP trims ASCII spaces itself
def test_a_blank_key_is_422(api: Api, key: str | bytes) -> None:
    refused = post(api, {"seed": 1}, key)
    assert problem_parameter(refused) == "idempotency-key"
    assert "empty" in refused.json()["detail"]


def test_a_unicode_key_is_read_as_utf8_and_kept(api: Api) -> None:
    key = "clé-✓-日本"
    first = post(api, {"seed": 1}, key.encode())
    assert first.status_code == 202
    assert post(api, {"seed": 1}, key.encode()).json()["id"] == first.json()["id"]
    assert problem_parameter(post(api, {"seed": 2}, key.encode())) == "idempotency-key"
    # The key is the characters, not the bytes: another spelling is another key.
    assert post(api, {"seed": 2}, "cle").status_code == 202


def test_a_key_that_is_not_utf8_is_422(api: Api) -> None:
    refused = post(api, {"seed": 1}, b"\xff\xfe-key")
    assert problem_parameter(refused) == "idempotency-key"
    assert "UTF-8" in refused.json()["detail"]


def test_a_key_over_200_characters_is_422(api: Api) -> None:
    assert post(api, {"seed": 1}, ("é" * 200).encode()).status_code == 202
    refused = post(api, {"seed": 1}, ("é" * 201).encode())
    assert problem_parameter(refused) == "idempotency-key"
    assert "201 characters" in refused.json()["detail"]
    assert problem_parameter(post(api, {"seed": 1}, "k" * 900)) == "idempotency-key"


def test_an_expired_key_makes_a_new_job(sqlite_url: str) -> None:
    settings = Settings(database_url=sqlite_url, idempotency_ttl_s=1)
    upgrade(sqlite_url)
    with serve(create_app(settings)) as url, httpx.Client(base_url=url) as client:
        short_lived = Api(url=url, client=client, database_url=sqlite_url, store=None)  # type: ignore[arg-type]
        first = post(short_lived, {"seed": 1}, "k-1").json()
        time.sleep(1.1)
        fresh = post(short_lived, {"seed": 2}, "k-1")
        assert fresh.status_code == 202
        assert fresh.json()["id"] != first["id"]
        assert client.get(f"/jobs/{first['id']}").json()["scenario"]["seed"] == 1
