"""The API's contract without a worker: submission, listing, cancelling, and every 4xx."""

from __future__ import annotations

import gc
from collections.abc import Iterator
from datetime import UTC, datetime
from typing import Any

import httpx
import pytest

from nanonav.settings import Settings
from nanonav.store import JobStatus, Outcome
from nanonav.store.migrate import upgrade
from service.app import create_app
from tests.conftest import Api, serve

PROBLEM = "application/problem+json"
RESULT_PATHS = (
    "metrics",
    "trajectory",
    "trajectory?format=npz",
    "qtable",
    "heatmap.png",
    "plots/learning.png",
)


def submit(api: Api, scenario: dict[str, Any] | None = None) -> dict[str, Any]:
    response = api.client.post("/jobs", json={} if scenario is None else scenario)
    assert response.status_code == 202, response.text
    body: dict[str, Any] = response.json()
    return body


def assert_problem(response: httpx.Response, status: int) -> dict[str, Any]:
    assert response.status_code == status, response.text
    assert response.headers["content-type"] == PROBLEM
    body: dict[str, Any] = response.json()
    assert body["status"] == status
    assert body["title"] and body["type"]
    return body


def test_submit_answers_202_with_location_and_the_resolved_scenario(api: Api) -> None:
    response = api.client.post("/jobs", json={})
    assert response.status_code == 202
    job = response.json()
    assert response.headers["location"] == f"/jobs/{job['id']}"
    assert job["status"] == "queued"
    assert job["scenario"]["learning"]["episodes"] == 50
    assert job["progress"] == {
        "episode": 0, "episodes": 50 + 20, "training_episodes": 50, "evaluation_worlds": 20,
        "fraction": 0.0, "decisions": None, "training_decisions": None, "training_curve": None,
    }  # fmt: skip
    # nothing to fetch yet: no result is advertised before it exists
    assert job["links"]["metrics"] is None and job["links"]["plots"] == {}
    assert job["links"]["cancel"] == f"/jobs/{job['id']}/cancel"
    assert api.store.get(job["id"]).status is JobStatus.QUEUED


def test_a_submit_without_a_seed_draws_one_and_keeps_it(api: Api) -> None:
    drawn = [submit(api, body)["scenario"]["seed"] for body in ({}, {}, {"preset": "hard-single"})]
    assert len(set(drawn)) == 3 and all(0 <= seed < 2**32 for seed in drawn)
    job = submit(api, {})
    assert (
        api.client.get(f"/jobs/{job['id']}").json()["scenario"]["seed"] == job["scenario"]["seed"]
    )
    assert submit(api, {"seed": 0})["scenario"]["seed"] == 0


def test_a_preset_is_applied_and_explicit_fields_override_it(api: Api) -> None:
    job = submit(api, {"preset": "paper-swarm", "robots": {"speed": 0.7}, "seed": 9})
    assert job["scenario"]["robots"]["count"] == 15
    assert job["scenario"]["robots"]["speed"] == 0.7
    assert job["scenario"]["seed"] == 9
    assert api.client.get(f"/jobs/{job['id']}").json()["scenario"] == job["scenario"]


def test_an_invalid_field_is_422_with_its_pointer(api: Api) -> None:
    body = assert_problem(api.client.post("/jobs", json={"robots": {"count": 0}}), 422)
    assert body["errors"][0]["pointer"] == "#/robots/count"
    assert body["errors"][0]["loc"] == ["body", "robots", "count"]
    assert "#/robots/count" in body["detail"]


def test_an_unknown_field_is_422(api: Api) -> None:
    body = assert_problem(api.client.post("/jobs", json={"robot": {"count": 1}}), 422)
    assert body["errors"][0]["pointer"] == "#/robot"


def test_pointers_escape_slash_and_tilde(api: Api) -> None:
    body = assert_problem(api.client.post("/jobs", json={"a/b~c": 1}), 422)
    assert body["errors"][0]["pointer"] == "#/a~1b~0c"


def test_a_scenario_over_the_work_budget_is_refused_with_422(api: Api) -> None:
    scenario = {"robots": {"count": 10_000}, "learning": {"max_steps": 100_000, "episodes": 1}}
    body = assert_problem(api.client.post("/jobs", json=scenario), 422)
    assert body["type"].endswith("budget-exceeded")
    assert {e["pointer"] for e in body["errors"]} == {
        "#/robots/count",
        "#/learning/max_steps",
        "#/learning/episodes",
        "#/evaluation/worlds",
    }
    assert api.store.page(status=None, limit=10, before_id=None).jobs == []


def test_a_cheap_count_of_robot_steps_over_the_work_budget_is_refused(api: Api) -> None:
    # 25 million robot-steps (2.5 % of the robot-step budget) among 100,000 emitters would
    # hold a worker for nearly two hours (2.6 ns an emitter's term here)
    scenario: dict[str, Any] = {
        "cells": {"count": 100},
        "biomarker": {"model": "inverse_square", "emitters_per_cell": 1000},
        "robots": {"count": 25},
        "learning": {"episodes": 999, "max_steps": 1000},
    }
    body = assert_problem(api.client.post("/jobs", json=scenario), 422)
    assert body["type"].endswith("budget-exceeded")
    assert "100000 field sources" in body["detail"]
    assert "#/biomarker/emitters_per_cell" in {e["pointer"] for e in body["errors"]}
    scenario["learning"]["episodes"] = 29  # a thirtieth of it (and its evaluation) fits
    assert api.client.post("/jobs", json=scenario).status_code == 202


def test_the_budget_comes_from_the_settings(sqlite_url: str) -> None:
    from nanonav.store.migrate import upgrade

    upgrade(sqlite_url)
    app = create_app(Settings(database_url=sqlite_url, robot_steps_budget=1000))
    with serve(app) as url, httpx.Client(base_url=url) as client:
        small = {"learning": {"episodes": 9, "max_steps": 100}, "evaluation": {"worlds": 1}}
        assert client.post("/jobs", json=small).status_code == 202
        small["evaluation"]["worlds"] = 2
        assert client.post("/jobs", json=small).status_code == 422


def test_malformed_json_is_400(api: Api) -> None:
    response = api.client.post(
        "/jobs", content=b'{"seed": ', headers={"content-type": "application/json"}
    )
    problem = assert_problem(response, 400)
    assert problem["type"].endswith("malformed-json")
    assert "at character 9" in problem["detail"]
    assert problem["errors"][0]["pointer"] == "#"  # the body, not a member "1" of it


@pytest.mark.parametrize(
    ("body", "said"),
    [
        (b'{"seed": 1, "name": "\xff"}', "it is not UTF-8 (invalid start byte at byte 21)"),
        (b"[" * 5000 + b"]" * 5000, "its arrays and objects nest too deeply"),
        (b'{"seed": ' + b"9" * 5000 + b"}", "it has a number of more than 4300 digits"),
    ],
    ids=["not-utf-8", "5000-deep", "5000-digits"],
)
def test_a_body_no_parser_reads_says_why(api: Api, body: bytes, said: str) -> None:
    """Not "There was an error parsing the body": what is wrong with it, as for malformed JSON."""
    response = api.client.post("/jobs", content=body, headers={"content-type": "application/json"})
    problem = assert_problem(response, 400)
    assert problem["type"].endswith("malformed-json")
    assert problem["detail"].startswith("the request body is not valid JSON: " + said)
    assert problem["errors"][0]["pointer"] == "#"


@pytest.mark.parametrize("content_type", ["text/plain", "application/x-www-form-urlencoded", None])
def test_a_body_not_declared_as_json_is_415(api: Api, content_type: str | None) -> None:
    headers = {} if content_type is None else {"content-type": content_type}
    assert_problem(api.client.post("/jobs", content=b"{}", headers=headers), 415)


def test_a_missing_body_is_422(api: Api) -> None:
    assert_problem(api.client.post("/jobs"), 422)


def test_a_body_over_the_limit_is_413_by_its_length(api: Api) -> None:
    big = b'{"seed": 1' + b" " * (65 * 1024) + b"}"
    response = api.client.post("/jobs", content=big, headers={"content-type": "application/json"})
    assert_problem(response, 413)


def test_a_streamed_body_over_the_limit_is_413(api: Api) -> None:
    def chunks() -> Iterator[bytes]:
        yield b'{"seed": 1'
        for _ in range(70):
            yield b" " * 1024
        yield b"}"

    response = api.client.post(
        "/jobs", content=chunks(), headers={"content-type": "application/json"}
    )
    assert "content-length" not in response.request.headers
    assert_problem(response, 413)


@pytest.mark.parametrize(
    ("path", "parameter"),
    [
        ("/jobs?limit=-1", "limit"),
        ("/jobs?limit=0", "limit"),
        ("/jobs?limit=1000", "limit"),
        ("/jobs?limit=ten", "limit"),
        ("/jobs?cursor=garbage", "cursor"),
        ("/jobs?cursor=%FF%FE", "cursor"),
        ("/jobs?cursor=LTE", "cursor"),
        ("/jobs?status=done", "status"),
        ("/jobs/abc", "job_id"),
        ("/jobs/0", "job_id"),
        ("/jobs/-3", "job_id"),
        ("/jobs/1e3", "job_id"),
        ("/jobs/99999999999999999999999", "job_id"),
        ("/jobs/1/trajectory?stride=0", "stride"),
        ("/jobs/1/trajectory?stride=x", "stride"),
        ("/jobs/1/trajectory?format=xml", "format"),
        ("/jobs/1/heatmap.png?plane=xx", "plane"),
        ("/jobs/1/heatmap.png?resolution=19", "resolution"),
        ("/jobs/1/heatmap.png?resolution=401", "resolution"),
        ("/jobs/1/heatmap.png?resolution=1.5", "resolution"),
        ("/jobs/1/heatmap.png?at=x", "at"),
        ("/jobs/1/heatmap.png?at=nan", "at"),
        ("/jobs/1/heatmap.png?at=inf", "at"),
        ("/jobs/1/heatmap.png?at=25.5", "at"),
        ("/jobs/1/plots/radar.png", "name"),
    ],
)
def test_bad_parameters_are_422_naming_the_parameter(api: Api, path: str, parameter: str) -> None:
    submit(api)
    body = assert_problem(api.client.get(path), 422)
    assert body["errors"][0]["parameter"] == parameter


def test_an_unknown_job_is_404(api: Api) -> None:
    for path in ("/jobs/77", "/jobs/77/metrics", "/jobs/77/plots/trajectory.png"):
        assert_problem(api.client.get(path), 404)
    assert_problem(api.client.post("/jobs/77/cancel"), 404)


def test_results_of_a_job_that_has_not_succeeded_are_409(api: Api) -> None:
    job = submit(api)
    for path in RESULT_PATHS:
        body = assert_problem(api.client.get(f"/jobs/{job['id']}/{path}"), 409)
        assert "queued" in body["detail"]


def test_cancel_of_a_queued_job_is_immediate(api: Api) -> None:
    job = submit(api)
    response = api.client.post(f"/jobs/{job['id']}/cancel")
    assert response.status_code == 200
    assert response.json()["status"] == "cancelled"
    assert response.json()["finished_at"] is not None
    assert api.client.post(f"/jobs/{job['id']}/cancel").json()["status"] == "cancelled"
    assert_problem(api.client.get(f"/jobs/{job['id']}/metrics"), 409)


def test_cancel_of_a_failed_job_is_409(api: Api) -> None:
    job = submit(api)
    claim = api.store.claim("test", lease_s=30)
    assert claim is not None
    api.store.fail(claim, "boom")
    body = assert_problem(api.client.post(f"/jobs/{job['id']}/cancel"), 409)
    assert "failed" in body["detail"]


def test_cancel_is_200_while_a_job_is_or_will_be_cancelled_and_409_once_it_succeeded(
    api: Api,
) -> None:
    job = submit(api)
    claim = api.store.claim("test", lease_s=30)
    assert claim is not None
    for _ in range(2):  # a running job: asked to stop, and asking again changes nothing
        response = api.client.post(f"/jobs/{job['id']}/cancel")
        assert response.status_code == 200
        assert response.json()["status"] == "running" and response.json()["cancel_requested"]
    done = submit(api, {"seed": 2})
    claim = api.store.claim("test", lease_s=30)
    assert claim is not None and claim.job.id == done["id"]
    api.store.finish(claim, Outcome(completed=True, metrics={}, trajectory=None, qtable=None))
    body = assert_problem(api.client.post(f"/jobs/{done['id']}/cancel"), 409)
    assert "succeeded" in body["detail"]


def test_the_job_list_is_newest_first_and_follows_its_cursor(api: Api) -> None:
    ids = [submit(api, {"seed": i})["id"] for i in range(5)]
    api.client.post(f"/jobs/{ids[0]}/cancel")
    seen: list[int] = []
    url: str | None = "/jobs?limit=2"
    while url is not None:
        page = api.client.get(url).json()
        assert len(page["jobs"]) <= 2
        seen += [j["id"] for j in page["jobs"]]
        url = page["next"]
    assert seen == ids[::-1]
    cancelled = api.client.get("/jobs", params={"status": "cancelled"}).json()
    assert [j["id"] for j in cancelled["jobs"]] == [ids[0]]
    assert cancelled["next_cursor"] is None


def test_unknown_routes_and_methods_are_problems(api: Api) -> None:
    assert_problem(api.client.get("/nowhere"), 404)
    assert_problem(api.client.delete("/jobs"), 405)


@pytest.mark.parametrize(
    "body",
    [
        b"[]",
        b"null",
        b"1",
        b'"x"',
        b'{"seed": -1}',
        b'{"seed": 1e400}',
        b'{"seed": 99999999999999999999999999}',
        b'{"space": {"size": NaN}}',
        b'{"space": {"size": Infinity}}',
        b'{"learning": {"epsilon_end": 0.9, "epsilon_start": 0.1}}',
        b'{"obstacles": {"count": 1000, "radius": 10}}',
        b'{"preset": "nope"}',
        b'{"preset": 3}',
        b"\xff\xfe\x00",
        b"[" * 5000 + b"]" * 5000,
        b'{"robots": {"count": 1, "count": 2}}',
    ],
)
def test_no_body_a_client_can_send_gives_a_500(api: Api, body: bytes) -> None:
    response = api.client.post("/jobs", content=body, headers={"content-type": "application/json"})
    assert 400 <= response.status_code < 500 or response.status_code == 202, response.text
    assert response.headers["content-type"] in (PROBLEM, "application/json")


def test_healthz_is_ok_at_head(api: Api) -> None:
    assert api.client.get("/healthz").json()["status"] == "ok"


def test_healthz_says_while_no_worker_is_ready_that_a_job_would_wait(api: Api) -> None:
    health = api.client.get("/healthz").json()
    assert health["status"] == "ok" and health["queue"]["queued"] == 0
    assert "no worker has been seen in the last 30 s" in health["note"]
    api.store.worker_seen("host:7", started_at=datetime.now(UTC))
    assert api.client.get("/healthz").json()["note"] is None


def test_healthz_says_why_queued_jobs_wait(api: Api) -> None:
    submit(api)
    health = api.client.get("/healthz").json()
    assert health["queue"]["queued"] == 1
    assert health["workers"] == {"seen": 0, "preparing": 0, "window_s": 30.0}
    assert health["note"].startswith("1 job is queued but no worker has been seen")
    api.store.worker_seen("host:7", started_at=datetime.now(UTC))
    health = api.client.get("/healthz").json()
    assert health["workers"]["seen"] == 1 and health["note"] is None


def test_healthz_is_503_on_an_unmigrated_database(sqlite_url: str) -> None:
    with serve(create_app(Settings(database_url=sqlite_url))) as url:
        response = httpx.get(f"{url}/healthz")
    assert response.status_code == 503
    assert response.json()["revision"] is None


def test_version_and_presets(api: Api) -> None:
    assert api.client.get("/version").json()["name"] == "nanonav"
    presets = api.client.get("/presets").json()
    assert presets["paper-swarm"]["robots"]["count"] == 15
    assert presets["paper-single"]["robots"]["count"] == 1


def test_openapi_documents_every_route_with_models_and_examples(api: Api) -> None:
    spec = api.client.get("/openapi.json").json()
    paths = spec["paths"]
    for path in (
        "/jobs",
        "/jobs/{job_id}",
        "/jobs/{job_id}/cancel",
        "/jobs/{job_id}/metrics",
        "/jobs/{job_id}/trajectory",
        "/jobs/{job_id}/qtable",
        "/jobs/{job_id}/heatmap.png",
        "/jobs/{job_id}/plots/{name}.png",
        "/presets",
        "/healthz",
        "/version",
    ):
        assert path in paths, path
    schemas = spec["components"]["schemas"]
    for name in ("Job", "JobPage", "Metrics", "Trajectory", "QTable", "Problem"):
        assert schemas[name].get("examples"), name
    post = paths["/jobs"]["post"]
    assert "application/problem+json" in post["responses"]["422"]["content"]
    assert post["requestBody"]["content"]["application/json"]["examples"]
    assert "image/png" in paths["/jobs/{job_id}/heatmap.png"]["get"]["responses"]["200"]["content"]
    assert api.client.get("/docs").status_code == 200


def test_a_server_fault_is_a_problem_document_without_details(sqlite_url: str) -> None:
    app = create_app(Settings(database_url=sqlite_url))

    def explode() -> None:
        raise RuntimeError("secret internals")

    app.add_api_route("/explode", explode)
    with serve(app) as url:
        response = httpx.get(f"{url}/explode")
    body = assert_problem(response, 500)
    assert "secret" not in response.text
    assert body["type"].endswith("internal-error")


def test_a_cancelled_job_serves_what_it_kept_and_advertises_only_that(api: Api) -> None:
    from nanonav.engine import simulate
    from nanonav.scenario import Scenario
    from worker.job import outcome

    scenario = Scenario.model_validate({"learning": {"episodes": 20_000, "max_steps": 200}})
    job = api.store.enqueue(scenario.model_dump(mode="json"), robot_steps=1, episodes=20_020)
    claim = api.store.claim("test", lease_s=30)
    assert claim is not None
    stopped = simulate(scenario, lambda progress: False)  # stopped after its first chunk
    assert not stopped.completed and stopped.qtable is not None
    api.store.finish(claim, outcome(stopped))
    answer = api.client.get(f"/jobs/{job.id}").json()
    assert answer["status"] == "cancelled"
    links = answer["links"]
    assert set(links["plots"]) == {"learning", "qtable"}
    assert links["trajectory"] is None and links["heatmap"] is None
    assert api.client.get(links["metrics"]).json()["completed"] is False
    assert len(api.client.get(links["qtable"]).json()["greedy"]) == 72
    for picture in links["plots"].values():
        response = api.client.get(picture)
        assert response.status_code == 200 and response.content.startswith(b"\x89PNG")
    assert api.client.get(f"/jobs/{job.id}/plots/trajectory.png").status_code == 409


def test_a_serving_api_keeps_its_start_up_objects_out_of_full_collections(
    sqlite_url: str,
) -> None:
    # A full pass over everything imported stalled every request for 100-150 ms under load.
    upgrade(sqlite_url)
    gc.unfreeze()
    with serve(create_app(Settings(database_url=sqlite_url))) as url:
        assert gc.get_freeze_count() > 10_000
        assert httpx.get(f"{url}/healthz").status_code == 200
    assert gc.get_freeze_count() == 0  # and an app that has stopped can be collected
