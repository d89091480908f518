"""ETags and Cache-Control: a 304 while an answer is the same, a new tag once it changes, and
finished results that say they never change."""

from __future__ import annotations

import httpx
import pytest
from starlette.applications import Starlette
from starlette.requests import Request
from starlette.responses import Response, StreamingResponse
from starlette.routing import Route

from nanonav.store import Outcome
from service.caching import IMMUTABLE, ETags, etag, none_match
from tests.conftest import Api, serve
from tests.service.test_api import assert_problem

IMMUTABLE_VALUE = IMMUTABLE["Cache-Control"]
GRID = {"grid": {"robots.count": [1, 2]}, "seeds": [0]}


@pytest.mark.parametrize(
    ("header", "matches"),
    [
        ('"abc"', True),
        ('W/"abc"', True),  # If-None-Match compares weakly
        ('"x", "abc"', True),
        ('"x",W/"abc" , "y"', True),
        ("*", True),
        (" * ", True),
        ('"x", "y"', False),
        ('"ab"', False),
        ('"abc,def"', False),  # a comma inside a tag is part of it
        ("abc", False),  # not a quoted tag
        ("", False),
    ],
)
def test_if_none_match_reads_lists_weak_tags_and_star(header: str, matches: bool) -> None:
    assert none_match(header, '"abc"') is matches


def test_a_tag_is_strong_and_follows_the_bytes() -> None:
    tag = etag(b'{"id": 1}')
    assert tag.startswith('"') and tag.endswith('"') and not tag.startswith("W/")
    assert tag == etag(b'{"id": 1}') != etag(b'{"id": 2}')


def test_a_polled_job_is_304_until_it_changes(api: Api) -> None:
    job_id = api.client.post("/jobs", json={}).json()["id"]
    first = api.client.get(f"/jobs/{job_id}")
    tag = first.headers["etag"]
    assert tag == etag(first.content)
    assert first.headers["cache-control"] == "no-cache"

    again = api.client.get(f"/jobs/{job_id}", headers={"If-None-Match": tag})
    assert again.status_code == 304 and again.content == b""
    assert again.headers["etag"] == tag
    assert again.headers["cache-control"] == "no-cache"
    assert "content-type" not in again.headers
    listed = api.client.get(f"/jobs/{job_id}", headers={"If-None-Match": f'"other", {tag}'})
    assert listed.status_code == 304
    assert api.client.get(f"/jobs/{job_id}", headers={"If-None-Match": "*"}).status_code == 304

    claim = api.store.claim("test", lease_s=30)
    assert claim is not None
    changed = api.client.get(f"/jobs/{job_id}", headers={"If-None-Match": tag})
    assert changed.status_code == 200 and changed.json()["status"] == "running"
    assert changed.headers["etag"] not in (tag, None)
    assert changed.headers["etag"] == etag(changed.content)


def test_lists_and_studies_are_tagged_and_answer_304(api: Api) -> None:
    api.client.post("/jobs", json={})
    study = api.client.post("/studies", json={"base": {}} | GRID).json()
    for path in ("/jobs", "/studies", f"/studies/{study['id']}", "/jobs?status=queued"):
        first = api.client.get(path)
        assert first.status_code == 200 and first.headers["cache-control"] == "no-cache"
        again = api.client.get(path, headers={"If-None-Match": first.headers["etag"]})
        assert again.status_code == 304, path
    before = api.client.get("/jobs").headers["etag"]
    api.client.post("/jobs", json={})
    assert api.client.get("/jobs", headers={"If-None-Match": before}).status_code == 200


def test_a_finished_jobs_results_are_immutable_and_tagged(api: Api, trained: int) -> None:
    for path in ("metrics", "qtable", "trajectory", "trajectory?format=npz", "heatmap.png"):
        first = api.client.get(f"/jobs/{trained}/{path}")
        assert first.status_code == 200, path
        assert first.headers["cache-control"] == IMMUTABLE_VALUE, path
        assert first.headers["etag"] == etag(first.content), path
        again = api.client.get(f"/jobs/{trained}/{path}", headers={"If-None-Match": "*"})
        assert again.status_code == 304 and again.content == b"", path
    streamed = api.client.get(f"/jobs/{trained}/trajectory?format=csv")
    assert streamed.headers["cache-control"] == IMMUTABLE_VALUE
    assert "etag" not in streamed.headers  # sent as it is made: no digest of the whole


def test_a_study_table_is_immutable_only_once_the_study_has_finished(api: Api) -> None:
    study_id = api.client.post("/studies", json={"base": {}} | GRID).json()["id"]
    path = f"/studies/{study_id}/results.csv"
    assert api.client.get(path).headers["cache-control"] == "no-cache"
    while (claim := api.store.claim("test", lease_s=30)) is not None:
        api.store.finish(claim, Outcome(completed=True, metrics={}, trajectory=None, qtable=None))
    finished = api.client.get(path)
    assert finished.headers["cache-control"] == IMMUTABLE_VALUE
    assert api.client.get(
        path, headers={"If-None-Match": finished.headers["etag"]}
    ).status_code == (304)


def test_errors_writes_and_event_streams_get_no_tag(api: Api) -> None:
    missing = api.client.get("/jobs/999", headers={"If-None-Match": "*"})
    assert_problem(missing, 404)
    assert "etag" not in missing.headers
    posted = api.client.post("/jobs", json={})
    assert posted.status_code == 202 and "etag" not in posted.headers
    job_id = posted.json()["id"]
    api.client.post(f"/jobs/{job_id}/cancel")
    stream = api.client.get(f"/jobs/{job_id}/events", headers={"If-None-Match": "*"})
    assert stream.status_code == 200 and "etag" not in stream.headers
    assert stream.headers["content-type"].startswith("text/event-stream")


def test_the_middleware_tags_large_bodies_keeps_a_routes_own_tag_and_passes_streams() -> None:
    large = b"x" * (3 << 20)  # hashed in a thread

    async def big(request: Request) -> Response:
        return Response(large, media_type="application/octet-stream")

    async def own(request: Request) -> Response:
        return Response(b"{}", media_type="application/json", headers={"ETag": '"v1"'})

    async def streamed(request: Request) -> Response:
        return StreamingResponse(iter([b"a", b"b"]), media_type="text/csv")

    routes = [Route("/big", big), Route("/own", own), Route("/streamed", streamed)]
    app = ETags(Starlette(routes=routes))
    with serve(app) as url, httpx.Client(base_url=url) as client:
        answer = client.get("/big")
        assert answer.headers["etag"] == etag(large) and answer.content == large
        assert client.get("/own").headers["etag"] == '"v1"'
        assert client.get("/own", headers={"If-None-Match": '"v1"'}).status_code == 304
        streamed_answer = client.get("/streamed", headers={"If-None-Match": "*"})
        assert streamed_answer.status_code == 200 and streamed_answer.content == b"ab"
        assert "etag" not in streamed_answer.headers
