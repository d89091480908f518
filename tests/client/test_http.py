"""What the client does with answers a healthy server rarely gives, through httpx's mock
transport: paging that stops at the limit, error bodies that are not problem documents, and
cells of a study table."""

from __future__ import annotations

import json
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

import httpx
import pytest

from nanonav.client import ApiError, Client, parse_cell


def job(job_id: int) -> dict[str, Any]:
    return {
        "id": job_id,
        "status": "succeeded",
        "progress": {"episode": 3, "episodes": 3, "fraction": 1.0},
        "scenario": {"seed": job_id},
        "created_at": "2026-11-22T04:00:00Z",
        "started_at": None,
        "finished_at": None,
        "error": None,
        "attempts": 1,
        "cancel_requested": False,
        "study_id": None,
        "links": {"self": f"/jobs/{job_id}"},
    }


@contextmanager
def client_for(answer: Any) -> Iterator[tuple[Client, list[httpx.Request]]]:
    """A client whose every request ``answer`` answers, and the requests it made."""
    requests: list[httpx.Request] = []

    def handle(request: httpx.Request) -> httpx.Response:
        requests.append(request)
        response: httpx.Response = answer(request)
        return response

    with Client("http://api.test", transport=httpx.MockTransport(handle)) as client:
        yield client, requests


def pages(request: httpx.Request) -> httpx.Response:
    """Jobs 9 down to 1, three to a page."""
    size = int(request.url.params["limit"])
    before = int(request.url.params.get("cursor", "10"))
    ids = list(range(before - 1, 0, -1))[:size]
    more = ids[-1] > 1
    return httpx.Response(
        200,
        json={
            "jobs": [job(i) for i in ids],
            "next_cursor": str(ids[-1]) if more else None,
            "next": f"/jobs?limit={size}&cursor={ids[-1]}" if more else None,
        },
    )


def test_jobs_follow_next_links_to_the_end() -> None:
    with client_for(pages) as (client, requests):
        assert [j.id for j in client.jobs()] == [9, 8, 7, 6, 5, 4, 3, 2, 1]
        assert requests[0].url.params["limit"] == "100"


def test_a_limit_asks_for_no_page_past_it() -> None:
    with client_for(pages) as (client, requests):
        found = list(client.jobs(status="succeeded", study=7, limit=3))
        assert [j.id for j in found] == [9, 8, 7]
        assert len(requests) == 1
        assert dict(requests[0].url.params) == {"limit": "3", "status": "succeeded", "study": "7"}
        with pytest.raises(ValueError, match="at least 1"):
            list(client.jobs(limit=0))


def test_an_error_that_is_not_a_problem_document_still_raises_api_error() -> None:
    gateway = httpx.Response(502, text="<html>Bad gateway</html>")
    with client_for(lambda request: gateway) as (client, _), pytest.raises(ApiError) as caught:
        client.job(1)
    assert (caught.value.status, caught.value.title) == (502, "Bad Gateway")
    assert caught.value.detail == "<html>Bad gateway</html>"
    assert caught.value.instance == "/jobs/1" and caught.value.errors == []


def test_a_success_that_is_not_json_is_named() -> None:
    hello = httpx.Response(200, text="hello")
    with (
        client_for(lambda request: hello) as (client, _),
        pytest.raises(ApiError, match=r"is http://api\.test a NanoNav API"),
    ):
        client.job(1)


def test_an_idempotency_key_is_sent_as_a_header() -> None:
    with client_for(lambda request: httpx.Response(202, json=job(4))) as (client, requests):
        assert client.submit({"seed": 4}, idempotency_key="k-1").id == 4
        assert requests[0].headers["idempotency-key"] == "k-1"
        assert json.loads(requests[0].content) == {"seed": 4}
        client.submit()
        assert "idempotency-key" not in requests[1].headers
        assert json.loads(requests[1].content) == {}


def test_field_errors_without_a_pointer_name_the_parameter() -> None:
    problem = {
        "type": "urn:nanonav:problem:invalid-input",
        "title": "Invalid input",
        "status": 422,
        "detail": "the request is invalid",
        "errors": [
            {"parameter": "limit", "loc": ["query", "limit"], "detail": "too big"},
            {"loc": ["header", "x"], "detail": "odd"},
        ],
    }
    with client_for(lambda request: httpx.Response(422, json=problem)) as (client, _):
        with pytest.raises(ApiError) as caught:
            client.job(1)
        assert str(caught.value).splitlines() == [
            "422 Invalid input: the request is invalid",
            "  limit: too big",
            "  header/x: odd",
        ]


@pytest.mark.parametrize(
    ("text", "value"),
    [
        ("", None),
        ("12", 12),
        ("-3", -3),
        ("0.25", 0.25),
        ("1e-05", 1e-05),
        ("True", True),
        ("False", False),
        ("q_learning", "q_learning"),
    ],
)
def test_study_table_cells_parse_to_their_values(text: str, value: Any) -> None:
    parsed = parse_cell(text)
    assert parsed == value and type(parsed) is type(value)


def test_keys_a_newer_server_adds_break_nothing() -> None:
    interval = {"n": 2, "mean": 1.5, "sd": 0.5, "ci_low": -3.0, "ci_high": 6.0, "median": 1.5}
    counts = {"total": 2, "queued": 0, "running": 0, "succeeded": 2, "failed": 0, "cancelled": 0}
    study = {
        "id": 3, "name": "", "status": "succeeded", "created_at": "2026-11-22T04:00:00+00:00",
        "cancel_requested": False, "jobs": {**counts, "paused": 0}, "links": {},
        "finished_at": None, "progress": 1.0, "spec": {"grid": {}, "seeds": [0, 1]},
        "interval": "t", "test": "w", "metrics": ["total_steps"], "comparisons": [],
        "points": [{"index": 0, "values": {}, "jobs": counts,
                    "metrics": {"total_steps": interval}}],
        "owner": "someone",
    }  # fmt: skip
    with client_for(lambda request: httpx.Response(200, json=study)) as (client, _):
        found = client.study(3)
    assert found.finished and found.jobs.finished == 2
    assert found.points[0].metrics["total_steps"].ci_high == 6.0
    assert found.raw["owner"] == "someone"


def test_an_older_server_without_the_interval_method_is_read_as_student_t() -> None:
    interval = {"n": 2, "mean": 1.5, "sd": 0.5, "ci_low": -3.0, "ci_high": 6.0}
    counts = {"total": 2, "queued": 0, "running": 0, "succeeded": 2, "failed": 0, "cancelled": 0}
    study = {
        "id": 3, "name": "", "status": "succeeded", "created_at": "2026-11-22T04:00:00+00:00",
        "cancel_requested": False, "jobs": counts, "links": {}, "finished_at": None,
        "progress": 1.0, "spec": {"grid": {}, "seeds": [0, 1]}, "interval": "t", "test": "w",
        "metrics": ["total_steps"], "comparisons": [],
        "points": [{"index": 0, "values": {}, "jobs": counts,
                    "metrics": {"total_steps": interval}}],
    }  # fmt: skip
    with client_for(lambda request: httpx.Response(200, json=study)) as (client, _):
        found = client.study(3)
    assert found.points[0].metrics["total_steps"].method == "student_t"
