"""Who may ask what: API keys, owners, quotas, cross-site requests and the Host header, against
a real API over a real SQLite file."""

from __future__ import annotations

import logging
import threading
from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any

import httpx
import pytest
from pydantic import ValidationError

from nanonav.settings import Settings
from nanonav.store import JobStatus, JobStore
from nanonav.store.migrate import upgrade
from service.app import create_app
from service.security import owner_of
from tests.conftest import SCRIPTED, serve
from tests.service.test_api import assert_problem
from worker.job import run_job

KEY_A = "alice-4Jq8vXz2Lr7Nw3Tb9Ks1Hd6Yp0Mf5Gc"
KEY_B = "bruno-8Rt2Wq6Zn1Vx5Lk9Jh3Dp7Cs0Bm4Fy"
TINY: dict[str, Any] = {"robots": {"count": 2}, "learning": {"episodes": 2, "max_steps": 60}}
STUDY: dict[str, Any] = {
    "name": "two policies",
    "base": {"learning": {"episodes": 1, "max_steps": 30}},
    "grid": {"robots.policy": ["q_learning", "gradient"]},
    "seeds": [1, 2],
}


def bearer(key: str) -> dict[str, str]:
    return {"Authorization": f"Bearer {key}", **SCRIPTED}


@dataclass
class Served:
    url: str
    client: httpx.Client
    store: JobStore
    settings: Settings


@contextmanager
def served(settings: Settings) -> Iterator[Served]:
    """The API over ``settings``' database, served by uvicorn, with a bare client."""
    upgrade(settings.database_url)
    store = JobStore.from_url(settings.database_url)
    try:
        with serve(create_app(settings)) as url, httpx.Client(base_url=url, timeout=30) as client:
            yield Served(url=url, client=client, store=store, settings=settings)
    finally:
        store.close()


@pytest.fixture
def keyed(sqlite_url: str) -> Iterator[Served]:
    with served(Settings(database_url=sqlite_url, api_keys=f"{KEY_A},{KEY_B}")) as api:
        yield api


def submit(api: Served, key: str | None, body: dict[str, Any], path: str = "/jobs") -> Any:
    headers = bearer(key) if key else SCRIPTED
    response = api.client.post(path, json=body, headers=headers)
    assert response.status_code == 202, response.text
    return response.json()


def run_next(api: Served) -> int:
    """Run the oldest queued job here, as a worker would; its id."""
    claim = api.store.claim("test", lease_s=30)
    assert claim is not None
    run_job(api.store, claim, api.settings, threading.Event())
    assert api.store.get(claim.job.id).status is JobStatus.SUCCEEDED
    return claim.job.id


# -- keys ------------------------------------------------------------------------------------


def test_without_a_key_every_route_but_healthz_answers_401_with_a_challenge(
    keyed: Served,
) -> None:
    for path in ("/jobs", "/jobs/1", "/studies", "/presets", "/version", "/openapi.json"):
        response = keyed.client.get(path)
        body = assert_problem(response, 401)
        assert response.headers["www-authenticate"] == 'Bearer realm="nanonav"'
        assert "Bearer" in body["detail"]
    assert keyed.client.get("/healthz").status_code == 200
    assert keyed.client.get("/static/app.css").status_code == 200
    assert keyed.client.get("/static/job.js").status_code == 401
    assert keyed.client.get("/presets", headers=bearer(KEY_A)).status_code == 200


def test_a_wrong_key_is_refused_without_being_repeated(
    keyed: Served, caplog: pytest.LogCaptureFixture
) -> None:
    wrong = "mallory-0Zx9Cv8Bn7Mq6Wr5Et4Yu3Io2Pa1Sd"
    caplog.set_level(logging.DEBUG)
    for headers in (bearer(wrong), {"Authorization": f"Basic {wrong}"}, bearer(KEY_A[:-1])):
        response = keyed.client.post("/jobs", json={}, headers=headers)
        assert_problem(response, 401)
        assert wrong not in response.text and KEY_A[:-1] not in response.text
    assert (
        "invalid_token"
        in keyed.client.get("/jobs", headers=bearer(wrong)).headers["www-authenticate"]
    )
    submit(keyed, KEY_A, {})
    assert wrong not in caplog.text and KEY_A not in caplog.text
    assert KEY_A not in repr(keyed.settings) and KEY_A not in str(keyed.settings.model_dump())


@pytest.mark.parametrize(
    ("keys", "why"),
    [
        ("short-key-9x", "shorter than 32"),
        (f"{KEY_A},changeme-changeme-changeme-changeme", "placeholder"),
        ("a" * 40, "placeholder"),
        ("bad key; 4Jq8vXz2Lr7Nw3Tb9Ks1Hd6Yp0Mf5Gc", "only letters"),
    ],
)
def test_short_or_placeholder_keys_stop_the_process_without_being_shown(
    sqlite_url: str, keys: str, why: str
) -> None:
    with pytest.raises(ValidationError) as error:
        Settings(database_url=sqlite_url, api_keys=keys)
    assert why in str(error.value)
    for key in keys.split(","):
        assert key not in str(error.value)


# -- owners ----------------------------------------------------------------------------------


def test_another_key_gets_404_for_every_route_of_a_job_and_a_study_it_did_not_make(
    keyed: Served,
) -> None:
    job = submit(keyed, KEY_A, TINY)["id"]
    assert run_next(keyed) == job
    study = submit(keyed, KEY_A, STUDY, "/studies")["id"]
    stored = keyed.store.get(job)
    assert stored.owner == owner_of(KEY_A) and KEY_A not in stored.owner
    job_paths = [
        f"/jobs/{job}", f"/jobs/{job}/metrics", f"/jobs/{job}/trajectory",
        f"/jobs/{job}/trajectory?format=npz", f"/jobs/{job}/trajectory?format=xyz",
        f"/jobs/{job}/qtable", f"/jobs/{job}/callback",
        f"/jobs/{job}/heatmap.png", f"/jobs/{job}/plots/learning.png", f"/jobs/{job}/events",
    ]  # fmt: skip
    study_paths = [
        f"/studies/{study}", f"/studies/{study}/results.csv",
        f"/studies/{study}/comparisons.csv", f"/studies/{study}/callback",
        f"/studies/{study}/plots/learning.png", f"/studies/{study}/events",
        f"/jobs?study={study}",
    ]  # fmt: skip
    for path in job_paths + study_paths:
        if not path.endswith(("/callback", f"/studies/{study}/events")):  # none, or endless
            assert keyed.client.get(path, headers=bearer(KEY_A)).status_code != 404, path
        body = assert_problem(keyed.client.get(path, headers=bearer(KEY_B)), 404)
        assert body["title"] in {"Job not found", "Study not found"}, path
    for path in (f"/jobs/{job}/cancel", f"/studies/{study}/cancel"):
        assert_problem(keyed.client.post(path, headers=bearer(KEY_B)), 404)
    for path in (f"/jobs/{job}", f"/studies/{study}"):
        assert_problem(keyed.client.delete(path, headers=bearer(KEY_B)), 404)
    assert keyed.store.get(job).status is JobStatus.SUCCEEDED
    assert keyed.client.get(f"/studies/{study}", headers=bearer(KEY_A)).json()["status"] == "queued"
    # a job's id that exists is answered exactly as one that does not
    missing = keyed.client.get("/jobs/999", headers=bearer(KEY_B)).json()
    theirs = keyed.client.get(f"/jobs/{job}", headers=bearer(KEY_B)).json()
    assert {k: v for k, v in missing.items() if k not in {"detail", "instance"}} == {
        k: v for k, v in theirs.items() if k not in {"detail", "instance"}
    }


def test_listings_show_only_the_callers_own_jobs_and_studies(keyed: Served) -> None:
    mine = {submit(keyed, KEY_A, {})["id"] for _ in range(2)}
    theirs = submit(keyed, KEY_B, {})["id"]
    study = submit(keyed, KEY_B, STUDY, "/studies")["id"]
    listed = keyed.client.get("/jobs", headers=bearer(KEY_A)).json()["jobs"]
    assert {j["id"] for j in listed} == mine
    listed_b = {j["id"] for j in keyed.client.get("/jobs", headers=bearer(KEY_B)).json()["jobs"]}
    assert theirs in listed_b and not listed_b & mine
    assert keyed.client.get("/studies", headers=bearer(KEY_A)).json()["studies"] == []
    studies_b = keyed.client.get("/studies", headers=bearer(KEY_B)).json()["studies"]
    assert [s["id"] for s in studies_b] == [study]


def test_policy_from_another_keys_job_is_refused_like_a_missing_job(keyed: Served) -> None:
    source = submit(keyed, KEY_A, TINY)["id"]
    run_next(keyed)
    reuse = {"policy_from": source, "learning": {"episodes": 0, "max_steps": 60},
             "robots": {"count": 2}}  # fmt: skip
    response = keyed.client.post("/jobs", json=reuse, headers=bearer(KEY_B))
    refused = assert_problem(response, 422)
    missing = {**reuse, "policy_from": 999}
    absent = assert_problem(keyed.client.post("/jobs", json=missing, headers=bearer(KEY_B)), 422)
    assert refused["errors"][0]["pointer"] == absent["errors"][0]["pointer"] == "#/policy_from"
    assert refused["detail"].replace(str(source), "N") == absent["detail"].replace("999", "N")
    study = {**STUDY, "base": reuse, "grid": {"evaluation.worlds": [1, 2]}}
    study_refused = keyed.client.post("/studies", json=study, headers=bearer(KEY_B))
    assert_problem(study_refused, 422)
    assert keyed.client.post("/jobs", json=reuse, headers=bearer(KEY_A)).status_code == 202


def test_idempotency_keys_are_scoped_per_owner(keyed: Served) -> None:
    def post(key: str) -> int:
        headers = {**bearer(key), "Idempotency-Key": "run-1"}
        response = keyed.client.post("/jobs", json={}, headers=headers)
        assert response.status_code == 202, response.text
        return int(response.json()["id"])

    first = post(KEY_A)
    assert post(KEY_A) == first
    other = post(KEY_B)
    assert other != first
    assert keyed.store.get(other).owner == owner_of(KEY_B)


# -- the dashboard ---------------------------------------------------------------------------


def test_a_browser_without_the_key_is_sent_to_the_login_page_and_logs_in_with_a_cookie(
    keyed: Served,
) -> None:
    page = keyed.client.get("/ui/jobs?status=queued", headers={"Accept": "text/html"})
    assert page.status_code == 303
    assert page.headers["location"] == "/ui/login?next=%2Fui%2Fjobs%3Fstatus%3Dqueued"
    login = keyed.client.get(page.headers["location"])
    assert login.status_code == 200 and 'id="login-form"' in login.text
    assert_problem(keyed.client.post("/ui/login", json={"key": KEY_A[::-1]}), 401)
    answer = keyed.client.post("/ui/login", json={"key": KEY_A})
    assert answer.status_code == 204
    cookie = answer.headers["set-cookie"]
    assert "HttpOnly" in cookie and "SameSite=Strict" in cookie
    # the client now holds the cookie, as a browser would
    assert keyed.client.get("/ui/jobs", headers={"Accept": "text/html"}).status_code == 200
    job = submit(keyed, None, {})["id"]
    assert keyed.store.get(job).owner == owner_of(KEY_A)
    mine = keyed.client.get(f"/ui/jobs/{job}")
    assert mine.status_code == 200
    other = submit(keyed, KEY_B, {})["id"]
    assert keyed.client.get(f"/ui/jobs/{other}").status_code == 404
    assert f"/ui/jobs/{other}" not in keyed.client.get("/ui/jobs").text
    assert keyed.client.post("/ui/logout", headers=SCRIPTED).status_code == 204
    assert_problem(keyed.client.get("/jobs"), 401)


# -- quotas ----------------------------------------------------------------------------------


def test_submits_past_the_active_jobs_quota_get_429_with_retry_after(sqlite_url: str) -> None:
    settings = Settings(database_url=sqlite_url, quota_active_jobs=3)
    with served(settings) as api:
        ids = [submit(api, None, {})["id"] for _ in range(3)]
        response = api.client.post("/jobs", json={}, headers=SCRIPTED)
        body = assert_problem(response, 429)
        assert int(response.headers["retry-after"]) > 0
        assert "active_jobs" in body["detail"] and "3" in body["detail"]
        small_study = {**STUDY, "seeds": [1]}
        assert_problem(api.client.post("/studies", json=small_study, headers=SCRIPTED), 429)
        api.client.post(f"/jobs/{ids[0]}/cancel", headers=SCRIPTED)
        submit(api, None, {})  # a finished job frees its place


def test_a_study_counts_all_its_jobs_and_robot_steps_are_a_quota_too(sqlite_url: str) -> None:
    settings = Settings(database_url=sqlite_url, quota_active_jobs=5)
    with served(settings) as api:
        queued = [submit(api, None, {})["id"] for _ in range(2)]
        body = assert_problem(api.client.post("/studies", json=STUDY, headers=SCRIPTED), 429)
        assert "adds 4" in body["detail"]
        for job in queued:
            api.client.post(f"/jobs/{job}/cancel", headers=SCRIPTED)
    budget = 2 * 60 * (2 + 20)  # robots x max_steps x (episodes + evaluation worlds)
    settings = Settings(database_url=sqlite_url, quota_robot_steps=budget * 2)
    with served(settings) as api:
        submit(api, None, TINY)
        submit(api, None, TINY)
        body = assert_problem(api.client.post("/jobs", json=TINY, headers=SCRIPTED), 429)
        assert "robot_steps" in body["detail"]


def test_a_submit_larger_than_its_quota_is_422_naming_the_quota_not_a_429(
    sqlite_url: str,
) -> None:
    settings = Settings(database_url=sqlite_url, quota_active_jobs=3)
    with served(settings) as api:
        response = api.client.post("/studies", json=STUDY, headers=SCRIPTED)
        body = assert_problem(response, 422)
        assert "retry-after" not in response.headers
        assert "active_jobs" in body["detail"] and "NANONAV_QUOTA_ACTIVE_JOBS" in body["detail"]
        assert {tuple(e["loc"]) for e in body["errors"]} == {("body", "grid"), ("body", "seeds")}
        assert {e["type"] for e in body["errors"]} == {"quota_never_fits"}
    budget = 2 * 60 * (2 + 20)  # robots x max_steps x (episodes + evaluation worlds)
    settings = Settings(database_url=sqlite_url, quota_robot_steps=budget - 1)
    with served(settings) as api:
        body = assert_problem(api.client.post("/jobs", json=TINY, headers=SCRIPTED), 422)
        assert "robot_steps" in body["detail"] and f"{budget:,}" in body["detail"]
        assert api.store.page(status=None, limit=10, before_id=None).jobs == []


def test_the_largest_study_the_server_takes_fits_the_default_quota(sqlite_url: str) -> None:
    settings = Settings(database_url=sqlite_url)
    assert settings.quota_active_jobs >= settings.study_max_jobs
    seeds = list(range(settings.study_max_jobs // 2))
    largest = {**STUDY, "base": {"learning": {"episodes": 1, "max_steps": 10}}, "seeds": seeds}
    with served(settings) as api:
        study = submit(api, None, largest, "/studies")
        assert study["jobs"]["total"] == settings.study_max_jobs


def test_concurrent_submits_never_pass_the_quota_together(sqlite_url: str) -> None:
    settings = Settings(database_url=sqlite_url, quota_active_jobs=5)
    with served(settings) as api:

        def post(_: int) -> int:
            with httpx.Client(base_url=api.url, timeout=60, headers=SCRIPTED) as client:
                return client.post("/jobs", json={}).status_code

        with ThreadPoolExecutor(max_workers=12) as pool:
            statuses = list(pool.map(post, range(24)))
        assert statuses.count(202) == 5 and statuses.count(429) == 19


def test_each_key_has_its_own_quota(sqlite_url: str) -> None:
    settings = Settings(database_url=sqlite_url, api_keys=f"{KEY_A},{KEY_B}", quota_active_jobs=1)
    with served(settings) as api:
        submit(api, KEY_A, {})
        assert_problem(api.client.post("/jobs", json={}, headers=bearer(KEY_A)), 429)
        submit(api, KEY_B, {})


def test_behind_a_local_proxy_each_forwarded_client_has_its_own_quota(sqlite_url: str) -> None:
    # uvicorn trusts X-Forwarded-For from a proxy on this machine (FORWARDED_ALLOW_IPS)
    with served(Settings(database_url=sqlite_url, quota_active_jobs=1)) as api:

        def from_client(address: str) -> httpx.Response:
            return api.client.post("/jobs", json={}, headers={"X-Forwarded-For": address})

        assert from_client("203.0.113.7").status_code == 202
        assert_problem(from_client("203.0.113.7"), 429)
        assert from_client("198.51.100.2").status_code == 202


def test_the_default_quota_refuses_a_flood_of_full_budget_jobs(sqlite_url: str) -> None:
    settings = Settings(database_url=sqlite_url)
    full = {
        "robots": {"count": 100, "policy": "random"},
        "obstacles": {"count": 0},
        "learning": {"episodes": 99, "max_steps": 100_000},
        "evaluation": {"worlds": 1},
    }
    with served(settings) as api:
        accepted = 0
        for _ in range(30):
            response = api.client.post("/jobs", json=full, headers=SCRIPTED)
            if response.status_code == 429:
                break
            assert response.status_code == 202, response.text
            accepted += 1
        assert accepted == settings.quota_robot_steps // settings.robot_steps_budget
        assert "robot_steps" in response.json()["detail"]


# -- cross-site requests and hosts ------------------------------------------------------------


def test_an_html_form_from_another_site_cannot_cancel_a_job(sqlite_url: str) -> None:
    with served(Settings(database_url=sqlite_url)) as api:
        job = submit(api, None, {})["id"]
        form = {"Content-Type": "application/x-www-form-urlencoded"}
        for headers in (form, {}, {"Content-Type": "text/plain"}):
            response = api.client.post(f"/jobs/{job}/cancel", content=b"", headers=headers)
            assert_problem(response, 415)
        evil = {**SCRIPTED, "Origin": "https://evil.example"}
        body = assert_problem(api.client.post(f"/jobs/{job}/cancel", headers=evil), 403)
        assert "evil.example" in body["detail"]
        assert api.store.get(job).status is JobStatus.QUEUED
        own = {**SCRIPTED, "Origin": api.url}
        assert api.client.post(f"/jobs/{job}/cancel", headers=own).status_code == 200
        json_only = {"Content-Type": "application/json"}
        assert api.client.post(f"/jobs/{job}/cancel", headers=json_only).status_code == 200
        # reads are not refused for their Origin
        assert (
            api.client.get("/jobs", headers={"Origin": "https://evil.example"}).status_code == 200
        )


def test_only_an_origin_of_the_same_scheme_host_and_port_is_the_apis_own(
    sqlite_url: str,
) -> None:
    https = {"X-Forwarded-Proto": "https"}  # uvicorn takes it from a proxy on this machine
    hosts = "localhost,127.0.0.1,::1"
    with served(Settings(database_url=sqlite_url, allowed_hosts=hosts)) as api:

        def write(origin: str, host: str | None = None, **headers: str) -> int:
            sent = {**SCRIPTED, "Origin": origin, **headers, **({"Host": host} if host else {})}
            status: int = api.client.post("/jobs", json={}, headers=sent).status_code
            assert status in {202, 403}, (origin, host, headers)
            return status

        port = api.url.rpartition(":")[2]
        assert write(f"http://127.0.0.1:{port}") == 202
        for other in ("https", "ftp", "ws", "file"):
            assert write(f"{other}://127.0.0.1:{port}") == 403, other
        assert write(f"https://127.0.0.1:{port}", **https) == 202
        assert write(f"http://127.0.0.1:{port}", **https) == 403
        # a port left out is the scheme's own, in the Origin or the Host
        plain = [("http://localhost", "localhost"), ("http://localhost:80", "localhost"),
                 ("http://localhost", "localhost:80"), ("http://[::1]", "[::1]:80"),
                 ("http://[::1]:8000", "[::1]:8000")]  # fmt: skip
        for origin, host in plain:
            assert write(origin, host) == 202, (origin, host)
            assert write(origin.replace("http:", "https:"), host) == 403, (origin, host)
        secure = [("https://localhost", "localhost"), ("https://localhost:443", "localhost"),
                  ("https://localhost", "localhost:443")]  # fmt: skip
        for origin, host in secure:
            assert write(origin, host, **https) == 202, (origin, host)
            assert write(origin.replace("https:", "http:"), host, **https) == 403, (origin, host)
        for origin in ("http://localhost:443", "http://localhost:8080", "http://localhost:080",
                       "http://localhost:x", "http://localhost:99999", "http://user@localhost",
                       "http://localhost/", "null", "localhost"):  # fmt: skip
            assert write(origin, "localhost") == 403, origin
        assert write("https://localhost:80", "localhost", **https) == 403


def test_allowed_origins_may_send_writes(sqlite_url: str) -> None:
    settings = Settings(database_url=sqlite_url, allowed_origins="https://lab.example.org")
    with served(settings) as api:
        lab = {"Origin": "https://lab.example.org"}
        assert api.client.post("/jobs", json={}, headers=lab).status_code == 202
        other = {"Origin": "https://lab.example.org.evil.example"}
        assert_problem(api.client.post("/jobs", json={}, headers=other), 403)
    with pytest.raises(ValidationError):
        Settings(database_url=sqlite_url, allowed_origins="lab.example.org")


def test_pages_of_allowed_origins_may_call_the_api_from_a_browser(sqlite_url: str) -> None:
    lab, evil = "https://lab.example.org", "https://evil.example"
    settings = Settings(database_url=sqlite_url, api_keys=KEY_A, allowed_origins=lab)
    with served(settings) as api:

        def preflight(origin: str) -> httpx.Response:
            return api.client.options("/jobs", headers={
                "Origin": origin,
                "Access-Control-Request-Method": "POST",
                "Access-Control-Request-Headers": "authorization, content-type, idempotency-key",
            })  # fmt: skip

        # a browser sends no key with its preflight: it is answered, not refused with 401
        allowed = preflight(lab)
        assert allowed.status_code == 200, allowed.text
        assert allowed.headers["access-control-allow-origin"] == lab
        assert "POST" in allowed.headers["access-control-allow-methods"].split(", ")
        asked = allowed.headers["access-control-allow-headers"].lower()
        assert {"authorization", "content-type", "idempotency-key"} <= set(asked.split(", "))
        refused = preflight(evil)
        assert refused.status_code == 400
        assert "access-control-allow-origin" not in refused.headers
        # the request itself still needs the key, and its answer may be read by the page
        origin = {"Origin": lab}
        assert api.client.post("/jobs", json={}, headers=origin).status_code == 401
        made = api.client.post("/jobs", json={}, headers={**origin, **bearer(KEY_A)})
        assert made.status_code == 202
        assert made.headers["access-control-allow-origin"] == lab
        read = api.client.get(f"/jobs/{made.json()['id']}", headers={**origin, **bearer(KEY_A)})
        assert read.headers["access-control-allow-origin"] == lab
        exposed = read.headers["access-control-expose-headers"].lower().split(", ")
        assert {"etag", "retry-after", "location"} <= set(exposed)
        # another origin's page gets no leave to read, and still may not write
        foreign = api.client.get("/healthz", headers={"Origin": evil})
        assert "access-control-allow-origin" not in foreign.headers
        forged = api.client.post("/jobs", json={}, headers={"Origin": evil, **bearer(KEY_A)})
        assert_problem(forged, 403)


def test_without_allowed_origins_no_preflight_is_answered(sqlite_url: str) -> None:
    with served(Settings(database_url=sqlite_url)) as api:
        asked = api.client.options("/jobs", headers={
            "Origin": "https://lab.example.org", "Access-Control-Request-Method": "POST"
        })  # fmt: skip
        assert asked.status_code == 405
        assert "access-control-allow-origin" not in asked.headers


def test_an_unknown_host_header_gets_400(sqlite_url: str) -> None:
    default = Settings.model_fields["allowed_hosts"].default
    with served(Settings(database_url=sqlite_url, allowed_hosts=default)) as api:
        refused = api.client.get("/healthz", headers={"Host": "rebound.example"})
        problem = assert_problem(refused, 400)
        assert problem["type"].endswith(":host-not-allowed")
        assert "rebound.example" in problem["detail"]
        assert_problem(api.client.get("/jobs", headers={"Host": "localhost.evil.example"}), 400)
        for host in ("localhost:8000", "127.0.0.1", "[::1]:8000", "LOCALHOST"):
            assert api.client.get("/healthz", headers={"Host": host}).status_code == 200, host
    settings = Settings(database_url=sqlite_url, allowed_hosts="nanonav.example.org,*.lab.org")
    with served(settings) as api:
        assert_problem(api.client.get("/healthz"), 400)
        for host in ("nanonav.example.org", "a.lab.org:443", "b.a.lab.org"):
            assert api.client.get("/healthz", headers={"Host": host}).status_code == 200, host
        for host in ("lab.org", "evil-lab.org", "nanonav.example.org.evil"):
            assert_problem(api.client.get("/healthz", headers={"Host": host}), 400)
    for pattern in ("example.*", "*example.org", "a.*.org"):
        with pytest.raises(ValidationError, match="stands alone"):
            Settings(database_url=sqlite_url, allowed_hosts=pattern)
