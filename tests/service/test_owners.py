"""Another key never reaches a job, study or policy it did not make, however the id in the path
is spelled: every route of the OpenAPI document that names one, every method, every spelling the
routes read as the same integer, on SQLite and PostgreSQL."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import pytest

from nanonav.engine import qlearning
from nanonav.settings import Settings
from nanonav.store import JobStatus
from tests.service.test_security import KEY_A, KEY_B, STUDY, TINY, Served, bearer, run_next, submit
from tests.service.test_security import served as served_api

# Spellings a path parameter typed ``int`` reads as the plain id: a sign, spaces and a line
# break around it, a fraction of zero.
SPELLINGS = ("{}", "+{}", "%20{}", "{}%20", "{}.0", "{}%0A", "0{}")
METHODS = ("GET", "HEAD", "POST", "PUT", "PATCH", "DELETE")
# Pages the OpenAPI document leaves out, by the id they name.
PAGES = {"job_id": ["/ui/jobs/{job_id}"], "study_id": ["/ui/studies/{study_id}",
         "/ui/studies/{study_id}/results"], "policy_id": ["/ui/policies/{policy_id}"]}  # fmt: skip
EXAMPLE_PARAMS = {"name": "learning"}


@pytest.fixture
def keyed_api(database_url: str) -> Iterator[Served]:
    settings = Settings(database_url=database_url, api_keys=f"{KEY_A},{KEY_B}")
    with served_api(settings) as api:
        yield api


def routes_naming(api: Served, parameter: str) -> dict[str, set[str]]:
    """Each path template that takes ``parameter``, with the methods the API answers on it."""
    document: dict[str, Any] = api.client.get("/openapi.json", headers=bearer(KEY_A)).json()
    found: dict[str, set[str]] = {}
    for template, operations in document["paths"].items():
        if "{" + parameter + "}" in template:
            methods = {method.upper() for method in operations}
            found[template] = methods | ({"HEAD"} if "GET" in methods else set())
    for page in PAGES[parameter]:
        found[page] = {"GET", "HEAD"}
    return found


def test_another_key_gets_only_404_on_every_route_method_and_id_spelling(
    keyed_api: Served,
) -> None:
    api = keyed_api
    job = submit(api, KEY_A, TINY)["id"]
    assert run_next(api) == job
    study = submit(api, KEY_A, STUDY, "/studies")["id"]
    states, actions = qlearning.labels("directions")
    table = {"states": states, "actions": actions, "greedy": []}
    sent = api.client.post("/policies", json=table, headers=bearer(KEY_A))
    assert sent.status_code == 201, sent.text
    policy = sent.json()["id"]
    tried = 0
    least = {"job_id": 9, "study_id": 6, "policy_id": 1}
    for parameter, own_id in (("job_id", job), ("study_id", study), ("policy_id", policy)):
        routes = routes_naming(api, parameter)
        assert len(routes) >= least[parameter], routes
        for template, allowed in routes.items():
            for spelling in SPELLINGS:
                path = template.replace("{" + parameter + "}", spelling.format(own_id))
                for name, value in EXAMPLE_PARAMS.items():
                    path = path.replace("{" + name + "}", value)
                for method in METHODS:
                    response = api.client.request(method, path, headers=bearer(KEY_B))
                    expected = 404 if method in allowed else 405
                    assert response.status_code == expected, (method, path, response.text)
                    tried += 1
    assert tried > 500
    assert api.store.get(job).status is JobStatus.SUCCEEDED
    assert api.client.get(f"/policies/{policy}", headers=bearer(KEY_A)).status_code == 200
    answer = api.client.get(f"/studies/{study}", headers=bearer(KEY_A))
    assert answer.status_code == 200 and answer.json()["status"] == "queued"
    # its own key too is answered only at the plain spelling (tests/service/test_ids.py)
    assert api.client.get(f"/jobs/+{job}", headers=bearer(KEY_A)).status_code == 404
