"""An id in a path is spelled one way, the plain decimal one: any other spelling of the number is
a 404 naming the plain path; a policy is also named by its ``policy_from`` name. A filter naming
a study that is not there is a 404; a JSON body that gives a key twice is a 400 naming it."""

from __future__ import annotations

import itertools
from collections.abc import Iterator
from typing import Any

import httpx
import pytest

from nanonav.engine import qlearning
from nanonav.scenario import MAX_EXACT_INT
from nanonav.settings import Settings
from service.json_keys import repeated_key
from tests.conftest import Api
from tests.service.test_api import assert_problem
from tests.service.test_security import KEY_A, STUDY, Served, bearer, served

# Spellings int() or pydantic read as the plain id: a sign, a leading zero, spaces and a line
# break around it, a fraction of zero.
SPELLINGS = ("+{}", "0{}", "%20{}", "{}%20", "{}%0A", "{}.0")
EXAMPLE_PARAMS = {"name": "learning"}
PAGES = {"job_id": ["/ui/jobs/{job_id}"], "study_id": ["/ui/studies/{study_id}",
         "/ui/studies/{study_id}/results"], "policy_id": ["/ui/policies/{policy_id}"]}  # fmt: skip
KIND = {"job_id": "job", "study_id": "study", "policy_id": "policy"}


def table_policy(api: Api) -> dict[str, Any]:
    states, actions = qlearning.labels("directions")
    sent = api.client.post("/policies", json={"states": states, "actions": actions, "greedy": []})
    assert sent.status_code == 201, sent.text
    answer: dict[str, Any] = sent.json()
    return answer


@pytest.fixture
def ids(api: Api) -> dict[str, int]:
    """A queued job, a queued study and a table policy, by the path parameter naming each."""
    job = api.client.post("/jobs", json={})
    study = api.client.post("/studies", json=STUDY)
    assert job.status_code == study.status_code == 202
    return {"job_id": job.json()["id"], "study_id": study.json()["id"],
            "policy_id": table_policy(api)["id"]}  # fmt: skip


def get_routes_naming(api: Api, parameter: str) -> list[str]:
    """Each path template of the API that takes ``parameter`` with GET, and the pages."""
    document: dict[str, Any] = api.client.get("/openapi.json").json()
    found = [
        t for t, ops in document["paths"].items() if "{" + parameter + "}" in t and "get" in ops
    ]
    return found


@pytest.mark.parametrize("parameter", ["job_id", "study_id", "policy_id"])
def test_another_spelling_of_an_id_is_a_404_naming_the_plain_path(
    api: Api, ids: dict[str, int], parameter: str
) -> None:
    plain_id = ids[parameter]
    routes = get_routes_naming(api, parameter)
    assert len(routes) >= {"job_id": 8, "study_id": 5, "policy_id": 2}[parameter]
    for template in routes:
        for spelling in SPELLINGS:
            path = template.replace("{" + parameter + "}", spelling.format(plain_id))
            for name, value in EXAMPLE_PARAMS.items():
                path = path.replace("{" + name + "}", value)
            plain = template.replace("{" + parameter + "}", str(plain_id))
            for name, value in EXAMPLE_PARAMS.items():
                plain = plain.replace("{" + name + "}", value)
            for method in ("GET", "HEAD"):
                response = api.client.request(method, path, headers={"Accept": "*/*"})
                assert response.status_code == 404, (method, path, response.text)
            problem = assert_problem(api.client.get(path), 404)
            kind = KIND[parameter]
            assert problem["type"].endswith(f"{kind}-not-found"), path
            spelled = httpx.URL(path).path.split("/")[2]
            assert problem["detail"] == (
                f"there is no {kind} {spelled!r}: an id is written in plain decimal digits, "
                f"as {plain}"
            ), path
    for template in PAGES[parameter]:
        for spelling in (*SPELLINGS, "x", "0", "1x"):
            path = template.replace("{" + parameter + "}", spelling.format(plain_id))
            page = api.client.get(path)
            assert page.status_code == 404, (path, page.text)
            assert page.headers["content-type"].startswith("text/html"), path
            assert "<h1>Not found</h1>" in page.text


def test_the_plain_spelling_still_answers(api: Api, ids: dict[str, int]) -> None:
    assert api.client.get(f"/jobs/{ids['job_id']}").json()["id"] == ids["job_id"]
    assert api.client.get(f"/studies/{ids['study_id']}").json()["id"] == ids["study_id"]
    assert api.client.get(f"/policies/{ids['policy_id']}").json()["id"] == ids["policy_id"]


def test_a_policy_is_also_named_as_policy_from_names_it(api: Api) -> None:
    sent = table_policy(api)
    name = sent["policy_from"]
    assert name == f"policy-{sent['id']}"
    answer = api.client.get(f"/policies/{name}")
    assert answer.status_code == 200, answer.text
    assert answer.json() == api.client.get(f"/policies/{sent['id']}").json()
    no_model = assert_problem(api.client.get(f"/policies/{name}/model"), 404)
    assert no_model["type"].endswith("no-model")
    odd = assert_problem(api.client.get(f"/policies/policy-0{sent['id']}"), 404)
    assert odd["detail"] == (
        f"there is no policy 'policy-0{sent['id']}': an id is written in plain decimal digits, "
        f"as /policies/{sent['id']}"
    )
    assert api.client.delete(f"/policies/{name}").status_code == 204
    gone = assert_problem(api.client.get(f"/policies/{name}"), 404)
    assert gone["type"].endswith("policy-not-found")


@pytest.mark.parametrize("spelled", ["two", "policy-", "policy-x", "policy-1-2", "0", "-1"])
def test_a_policy_path_that_names_no_id_is_a_422_naming_the_parameter(
    api: Api, spelled: str
) -> None:
    problem = assert_problem(api.client.get(f"/policies/{spelled}"), 422)
    [error] = problem["errors"]
    assert error["loc"] == ["path", "policy_id"] and error["parameter"] == "policy_id"
    assert error["detail"] == (
        f"must be a policy's id, an integer from 1, or its name, policy-<id>; not {spelled!r}"
    )


def test_jobs_of_a_study_that_is_not_there_is_a_404_naming_it(
    api: Api, ids: dict[str, int]
) -> None:
    problem = assert_problem(api.client.get("/jobs", params={"study": 99999}), 404)
    assert problem["type"].endswith("study-not-found")
    assert problem["detail"] == "there is no study 99999"
    listed = api.client.get("/jobs", params={"study": ids["study_id"]}).json()["jobs"]
    assert {job["study_id"] for job in listed} == {ids["study_id"]} and len(listed) == 4


def test_ui_jobs_new_is_the_new_job_form(api: Api) -> None:
    answer = api.client.get("/ui/jobs/new", params={"from": "3"}, follow_redirects=False)
    assert answer.status_code == 307 and answer.headers["location"] == "/?from=3"
    assert api.client.get("/ui/jobs/new", follow_redirects=False).headers["location"] == "/"
    page = api.client.get("/ui/jobs/new", follow_redirects=True)
    assert page.status_code == 200 and 'id="job-form"' in page.text


# ---------------------------------------------------------------- duplicate keys


@pytest.mark.parametrize(
    ("path", "body", "pointer", "key"),
    [
        ("/jobs", '{"seed": 1, "seed": 2}', "#/seed", "seed"),
        ("/jobs", '{"robots": {"count": 1, "policy": "random", "count": 2}}',
         "#/robots/count", "count"),
        ("/jobs", '{"preset": "paper-swarm", "learning": {}, "seed": 3, "learning": {}}',
         "#/learning", "learning"),
        ("/studies", '{"seeds": [1], "grid": {"robots.count": [1]}, "grid": {}}', "#/grid",
         "grid"),
        ("/studies", '{"seeds": [1], "grid": {"robots.count": [{"a": 1, "a": 1}]}}',
         "#/grid/robots.count/0/a", "a"),
        ("/policies", '{"states": [], "actions": [], "states": []}', "#/states", "states"),
        ("/ui/login", '{"key": "a", "key": "b"}', "#/key", "key"),
    ],
)  # fmt: skip
def test_a_key_given_twice_in_a_json_body_is_a_400_naming_it(
    api: Api, path: str, body: str, pointer: str, key: str
) -> None:
    before = api.client.get("/jobs").json()["jobs"]
    response = api.client.post(path, content=body, headers={"Content-Type": "application/json"})
    problem = assert_problem(response, 400)
    assert problem["type"].endswith("duplicate-key")
    assert problem["detail"] == f"{pointer}: the key {key!r} is given twice in the same object"
    [error] = problem["errors"]
    assert (error["pointer"], error["type"]) == (pointer, "duplicate_key")
    assert api.client.get("/jobs").json()["jobs"] == before


def test_the_same_key_in_different_objects_is_no_duplicate(api: Api) -> None:
    body = '{"seed": 4, "robots": {"count": 1}, "cells": {"count": 1}}'
    response = api.client.post("/jobs", content=body, headers={"Content-Type": "application/json"})
    assert response.status_code == 202, response.text
    assert response.json()["scenario"]["seed"] == 4


def test_a_body_nested_past_the_parsers_depth_is_no_duplicate_and_no_error() -> None:
    """The check reads the body before the route does: a body nested deeper than Python's
    parser goes is left for the route to refuse (400), not raised as a RecursionError."""
    deep = b"[" * 100_000 + b"]" * 100_000
    assert repeated_key(deep) is None
    assert repeated_key(b'{"a": [{"b": 1, "b": 2}]}') == ("a", 0, "b")


# ---------------------------------------------------------------- ids past 32 bits


@pytest.fixture
def wide(database_url: str) -> Iterator[Served]:
    """The API with a key, over a SQLite file and over PostgreSQL, holding the key's job, study
    and policy."""
    with served(Settings(database_url=database_url, api_keys=KEY_A)) as api:
        api.client.headers.update(bearer(KEY_A))
        for path, body in (("/jobs", {}), ("/studies", STUDY)):
            assert api.client.post(path, json=body).status_code == 202
        states, actions = qlearning.labels("directions")
        sent = {"states": states, "actions": actions, "greedy": []}
        assert api.client.post("/policies", json=sent).status_code == 201
        yield api


@pytest.mark.parametrize("missing", [2**31, 2**32, MAX_EXACT_INT])
def test_an_id_past_32_bits_is_a_404_on_every_route_naming_one(wide: Served, missing: int) -> None:
    document: dict[str, Any] = wide.client.get("/openapi.json").json()
    asked = 0
    for template, operations in document["paths"].items():
        for parameter, kind in KIND.items():
            if "{" + parameter + "}" not in template:
                continue
            spellings = [str(missing)] + (["policy-" + str(missing)] if kind == "policy" else [])
            for spelled, method in itertools.product(spellings, operations):
                path = template.replace("{" + parameter + "}", spelled).replace(
                    "{name}", "learning"
                )
                response = wide.client.request(method, path, headers={"Accept": "*/*"})
                problem = assert_problem(response, 404)
                assert problem["type"].endswith(f"{kind}-not-found"), (method, path)
                assert problem["detail"] == f"there is no {kind} {missing}", (method, path)
                asked += 1
    assert asked == 25


@pytest.mark.parametrize("cursor", ["80000000", "1fffffffffffff"])
def test_a_cursor_past_32_bits_lists_every_row_below_it(wide: Served, cursor: str) -> None:
    for path, key, count in (("/jobs", "jobs", 5), ("/studies", "studies", 1),
                             ("/policies", "policies", 1)):  # fmt: skip
        response = wide.client.get(path, params={"cursor": cursor, "limit": 100})
        assert response.status_code == 200, (path, response.text)
        assert len(response.json()[key]) == count and response.json()["next_cursor"] is None
    study_id = wide.client.get("/studies").json()["studies"][0]["id"]
    of_study = wide.client.get("/jobs", params={"study": study_id, "cursor": cursor})
    assert len(of_study.json()["jobs"]) == 4


@pytest.mark.parametrize("missing", [2**31, MAX_EXACT_INT])
def test_jobs_of_a_study_past_32_bits_is_a_404_naming_it(wide: Served, missing: int) -> None:
    problem = assert_problem(wide.client.get("/jobs", params={"study": missing}), 404)
    assert problem["type"].endswith("study-not-found")
    assert problem["detail"] == f"there is no study {missing}"


# The largest a job's id and a policy's may be in policy_from: a policy's name has 15 digits.
@pytest.mark.parametrize(("job_id", "policy_id"), [(2**31, 2**31), (MAX_EXACT_INT, 10**15 - 1)])
def test_a_policy_from_past_32_bits_is_a_422_saying_there_is_none(
    wide: Served, job_id: int, policy_id: int
) -> None:
    evaluate = {"robots": {"count": 2}, "learning": {"episodes": 0, "max_steps": 60}}
    for source, detail in ((job_id, f"there is no job {job_id}"),
                           (f"policy-{policy_id}", f"there is no policy {policy_id}")):  # fmt: skip
        for path, body, pointer in (
            ("/jobs", {**evaluate, "policy_from": source}, "#/policy_from"),
            ("/studies", {"base": {**evaluate, "policy_from": source}, "seeds": [1]},
             "#/base/policy_from"),
        ):  # fmt: skip
            problem = assert_problem(wide.client.post(path, json=body), 422)
            [error] = problem["errors"]
            assert (error["pointer"], error["type"]) == (pointer, "policy_unusable")
            assert error["detail"] == detail


@pytest.mark.parametrize("missing", [2**31, MAX_EXACT_INT])
def test_a_page_naming_an_id_past_32_bits_says_it_is_missing(wide: Served, missing: int) -> None:
    assert wide.client.post("/ui/login", json={"key": KEY_A}).status_code == 204
    for template in itertools.chain.from_iterable(PAGES.values()):
        page = wide.client.get(template.format(job_id=missing, study_id=missing,
                                               policy_id=missing))  # fmt: skip
        assert page.status_code == 404, (template, page.text)
        assert "<h1>Not found</h1>" in page.text
    for path, params in (
        ("/ui/jobs", {"study": missing}),
        ("/ui/jobs", {"cursor": "1fffffffffffff"}),
        ("/ui/studies", {"cursor": "1fffffffffffff"}),
        ("/ui/policies", {"cursor": "1fffffffffffff"}),
        ("/", {"from": missing, "policy": missing}),
    ):
        page = wide.client.get(path, params=params)
        assert page.status_code == 200, (path, params, page.text)
