"""What the OpenAPI document promises, pinned one rule at a time: HEAD wherever GET is, a true
``Allow`` on 405, numbers that are numbers, and cursors the document describes exactly."""

from __future__ import annotations

import re
from typing import Any

import pytest

from nanonav.scenario import MAX_EXACT_INT
from service.paging import CURSOR_PATTERN
from tests.conftest import Api
from tests.service.conftest import TINY
from tests.service.test_api import assert_problem, submit


def test_a_get_route_answers_head_with_its_headers_and_no_body(api: Api) -> None:
    job = submit(api)
    got = api.client.get(f"/jobs/{job['id']}")
    head = api.client.head(f"/jobs/{job['id']}")
    assert head.status_code == 200
    assert head.content == b""
    for name in ("content-type", "content-length", "etag", "cache-control"):
        assert head.headers[name] == got.headers[name], name
    assert int(head.headers["content-length"]) == len(got.content)


def test_head_of_a_missing_job_is_its_404_without_a_body(api: Api) -> None:
    head = api.client.head("/jobs/77")
    assert head.status_code == 404
    assert head.headers["content-type"] == "application/problem+json"
    assert head.content == b""


def test_head_of_a_stream_that_never_ends_answers_at_once(api: Api) -> None:
    job = submit(api)
    head = api.client.head(f"/jobs/{job['id']}/events", timeout=5)
    assert head.status_code == 200
    assert head.headers["content-type"].startswith("text/event-stream")
    assert head.content == b""


def test_head_of_a_streamed_download_has_its_headers(api: Api, trained: int) -> None:
    head = api.client.head(f"/jobs/{trained}/trajectory", params={"format": "csv"})
    assert head.status_code == 200
    assert head.headers["content-type"] == "text/csv; charset=utf-8"
    assert "attachment" in head.headers["content-disposition"]
    assert head.content == b""


@pytest.mark.parametrize(
    ("method", "path", "allow"),
    [
        ("PUT", "/jobs", "GET, HEAD, POST"),
        ("PATCH", "/jobs/1/qtable", "GET, HEAD"),
        ("PUT", "/jobs/1/metrics", "GET, HEAD"),
        ("GET", "/jobs/1/cancel", "POST"),
        ("HEAD", "/jobs/1/cancel", "POST"),
        ("OPTIONS", "/studies", "GET, HEAD, POST"),
        ("POST", "/healthz", "GET, HEAD"),
    ],
)
def test_a_405_lists_every_method_its_path_takes(
    api: Api, method: str, path: str, allow: str
) -> None:
    response = api.client.request(method, path)
    assert response.status_code == 405
    assert response.headers["allow"] == allow


def _paths(document: dict[str, Any]) -> dict[str, set[str]]:
    """Every path of the OpenAPI document, its parameters filled in (routing reads any value),
    with the methods it declares."""
    return {
        re.sub(r"\{[^}]+\}", "1", path): {method.upper() for method in operations}
        for path, operations in document["paths"].items()
    }


def test_every_path_of_the_document_says_in_allow_what_it_declares(api: Api) -> None:
    for path, declared in _paths(api.client.get("/openapi.json").json()).items():
        response = api.client.request("PATCH" if "PATCH" not in declared else "PUT", path)
        assert response.status_code == 405, path
        expected = declared | ({"HEAD"} if "GET" in declared else set())
        assert set(response.headers["allow"].split(", ")) == expected, path


def test_every_get_path_answers_head_as_it_answers_get(api: Api) -> None:
    for path, declared in _paths(api.client.get("/openapi.json").json()).items():
        if "GET" not in declared:
            continue
        got, head = api.client.get(path), api.client.head(path)
        assert head.status_code == got.status_code, path
        assert head.headers["content-type"] == got.headers["content-type"], path
        assert head.content == b"", path


@pytest.mark.parametrize(
    ("scenario", "pointer"),
    [
        ({"seed": True}, "#/seed"),
        ({"rewards": {"approach": False}}, "#/rewards/approach"),
        ({"robots": {"count": "5"}}, "#/robots/count"),
        ({"robots": {"count": 2.5}}, "#/robots/count"),
        ({"space": {"size": "50"}}, "#/space/size"),
        ({"space": {"walls": "true"}}, "#/space/walls"),
        ({"space": {"walls": 1}}, "#/space/walls"),
        ({"learning": {"epsilon_decay": True}}, "#/learning/epsilon_decay"),
        ({"policy_from": True}, "#/policy_from"),
        ({"seed": MAX_EXACT_INT + 1}, "#/seed"),
    ],
)
def test_a_value_of_the_wrong_json_type_is_422_naming_it(
    api: Api, scenario: dict[str, Any], pointer: str
) -> None:
    body = assert_problem(api.client.post("/jobs", json=scenario), 422)
    assert [error["pointer"] for error in body["errors"]] == [pointer]


def test_numbers_are_taken_as_json_schema_takes_them(api: Api) -> None:
    """An integer stands for a decimal number, and 2.0 is the integer 2."""
    scenario = {"space": {"size": 40}, "robots": {"count": 2.0}, "seed": MAX_EXACT_INT}
    job = submit(api, scenario)
    assert job["scenario"]["space"]["size"] == 40.0
    assert job["scenario"]["robots"]["count"] == 2
    assert job["scenario"]["seed"] == MAX_EXACT_INT


@pytest.mark.parametrize(
    ("study", "pointer"),
    [
        ({"seeds": [True]}, "#/seeds/0"),
        ({"replicates": True}, "#/replicates"),
        ({"replicates": "2"}, "#/replicates"),
        ({"replicates": 1, "grid": {"robots.count": [1, True]}}, "#/grid/robots.count/1"),
        ({"replicates": 1, "grid": {"rewards.approach": [1, False]}}, "#/grid/rewards.approach/1"),
        ({"replicates": 1, "grid": {"robots.count": [1, 1.0]}}, "#/grid/robots.count/1"),
    ],
)
def test_a_study_value_of_the_wrong_json_type_is_422_naming_it(
    api: Api, study: dict[str, Any], pointer: str
) -> None:
    body = assert_problem(api.client.post("/studies", json=study), 422)
    assert body["errors"][0]["pointer"] == pointer


def test_the_cursor_parameter_states_the_pattern_the_routes_accept(api: Api) -> None:
    document = api.client.get("/openapi.json").json()
    for path in ("/jobs", "/studies"):
        parameters = document["paths"][path]["get"]["parameters"]
        (cursor,) = [p for p in parameters if p["name"] == "cursor"]
        patterns = [s.get("pattern") for s in cursor["schema"].get("anyOf", [cursor["schema"]])]
        assert CURSOR_PATTERN in patterns, path


def test_every_cursor_given_out_matches_the_pattern_and_every_match_is_a_page(api: Api) -> None:
    for seed in range(3):
        submit(api, {**TINY, "seed": seed})
    page = api.client.get("/jobs", params={"limit": 1}).json()
    assert re.fullmatch(CURSOR_PATTERN, page["next_cursor"])
    assert len(api.client.get(page["next"]).json()["jobs"]) == 1
    for cursor in ("0", "1", "ffff", "1fffffffffffff"):
        response = api.client.get("/jobs", params={"cursor": cursor})
        assert response.status_code == 200, cursor
    assert api.client.get("/jobs", params={"cursor": "0"}).json()["jobs"] == []
    for cursor in ("20000000000000", "MzA", "-1", ""):
        body = assert_problem(api.client.get("/jobs", params={"cursor": cursor}), 422)
        assert body["errors"][0]["parameter"] == "cursor"


def test_ids_past_the_largest_exact_json_integer_are_422(api: Api) -> None:
    body = assert_problem(api.client.get(f"/jobs/{MAX_EXACT_INT + 1}"), 422)
    assert body["errors"][0]["parameter"] == "job_id"
    assert_problem(api.client.get(f"/jobs/{MAX_EXACT_INT}"), 404)


def test_the_document_states_each_grid_keys_values(api: Api) -> None:
    document = api.client.get("/openapi.json").json()
    grid = document["components"]["schemas"]["StudySpec"]["properties"]["grid"]
    assert "robots.count" in grid["propertyNames"]["enum"]
    assert "seed" not in grid["propertyNames"]["enum"]
    counts = grid["properties"]["robots.count"]
    assert counts["uniqueItems"] is True
    assert counts["items"] == {"type": "integer", "minimum": 1, "maximum": 100_000}
    assert grid["properties"]["robots.policy"]["items"]["enum"][0] == "q_learning"
    # a field that takes null is swept through it: its values' schema keeps null
    decay = grid["properties"]["learning.epsilon_decay"]["items"]["anyOf"]
    assert decay[0]["type"] == "number" and decay[1] == {"type": "null"}


def test_a_study_lists_seeds_and_grid_values_once_as_json_compares_them(api: Api) -> None:
    body = assert_problem(api.client.post("/studies", json={"seeds": [3, 3.0]}), 422)
    assert body["errors"][0]["pointer"] == "#/seeds"
    study = {"replicates": 1, "grid": {"space.walls": [True, False]}, "base": TINY}
    assert api.client.post("/studies", json=study).status_code == 202
