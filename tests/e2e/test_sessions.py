"""The dashboard's sessions across the API processes of one deployment, as real processes: a
logout through any one of them ends the session in every other."""

from __future__ import annotations

import re
import time
from pathlib import Path

import httpx
import pytest

from nanonav.store.migrate import upgrade
from service.sessions import SESSION_COOKIE
from tests.conftest import SCRIPTED, sqlite_url_in
from tests.processes import ApiServer
from tests.service.test_security import KEY_A

pytestmark = pytest.mark.timeout(240)
# Requests sent one connection each, so that the processes sharing a port all take some.
REPLAYS = 12


def logged_in(url: str) -> str:
    answer = httpx.post(f"{url}/ui/login", json={"key": KEY_A})
    assert answer.status_code == 204, answer.text
    match = re.match(rf"{SESSION_COOKIE}=([^;]+);", answer.headers["set-cookie"])
    assert match is not None
    return match.group(1)


def statuses(url: str, token: str) -> set[int]:
    """What ``GET /jobs`` with ``token`` as the cookie answers, over fresh connections."""
    cookie = {"Cookie": f"{SESSION_COOKIE}={token}"}
    return {httpx.get(f"{url}/jobs", headers=cookie).status_code for _ in range(REPLAYS)}


def log_out(url: str, token: str) -> None:
    headers = {**SCRIPTED, "Cookie": f"{SESSION_COOKIE}={token}"}
    assert httpx.post(f"{url}/ui/logout", headers=headers).status_code == 204


def test_a_logout_through_one_api_process_holds_in_every_other(tmp_path: Path) -> None:
    url = sqlite_url_in(tmp_path)
    upgrade(url)
    env = {"NANONAV_API_KEYS": KEY_A}
    shared = ApiServer(url, tmp_path / "shared.log", cwd=None, NANONAV_API_PROCESSES="2", **env)
    alone = ApiServer(url, tmp_path / "alone.log", cwd=None, **env)
    try:
        for api in (shared, alone):
            api.wait_ready()
        deadline = time.monotonic() + 60
        while shared.text().count("Application startup complete") < 2:
            assert time.monotonic() < deadline, shared.text()
            time.sleep(0.05)
        first, second = logged_in(shared.url), logged_in(alone.url)
        for api in (shared, alone):
            assert statuses(api.url, first) == statuses(api.url, second) == {200}
        log_out(alone.url, first)
        log_out(shared.url, second)
        for api in (shared, alone):
            assert statuses(api.url, first) == statuses(api.url, second) == {401}
        assert statuses(shared.url, logged_in(alone.url)) == {200}
    finally:
        shared.terminate()
        alone.terminate()
