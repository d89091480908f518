"""The dashboard's login: a signed, expiring session token in the cookie instead of the key, that
a logout ends on the server, and a page that only ever sends a person back to a path of this
site."""

from __future__ import annotations

import asyncio
import contextlib
import re
import time
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

import httpx
import pytest
from sqlalchemy import Engine, func, select
from sqlalchemy.exc import OperationalError

from nanonav.settings import Settings
from nanonav.store.migrate import upgrade
from nanonav.store.models import RevokedSession
from nanonav.store.revocations import RevocationStore
from service.app import create_app
from service.security import owner_of
from service.sessions import SESSION_COOKIE, issue, read_token, same_site_path
from tests.conftest import SCRIPTED, serve
from tests.service.test_api import assert_problem
from tests.service.test_security import KEY_A, KEY_B, Served, bearer, served

SECRET = "s3ss10n-9Qw2Er7Ty4Ui1Op6As3Df8Gh5Jk"
OTHER_SECRET = "r0tat3d-5Zx8Cv1Bn6Mq3Wr9Et2Yu7Io4Pa"
SESSION_ID = "0123456789abcdef0123456789abcdef"  # the shape of a session id, in no token issued


def logged_in(api: Served, key: str) -> str:
    """Log in with ``key``; the cookie's value."""
    answer = api.client.post("/ui/login", json={"key": key})
    assert answer.status_code == 204, answer.text
    match = re.match(rf"{SESSION_COOKIE}=([^;]+);", answer.headers["set-cookie"])
    assert match is not None
    return match.group(1)


def cookie_header(token: str | bytes) -> dict[str, Any]:
    """The Cookie header that carries ``token`` as the session; bytes are sent as they are.
    (A bytes value under a str name: httpx sends it, its annotations have no such header.)"""
    raw = token if isinstance(token, bytes) else token.encode()
    return {"Cookie": SESSION_COOKIE.encode() + b"=" + raw}


def with_cookie(api: Served, token: str | bytes) -> httpx.Response:
    """GET /jobs with ``token`` as the session cookie, as a fresh client sends it."""
    return httpx.get(f"{api.url}/jobs", headers=cookie_header(token))


def logged_out(api: Served, token: str | None) -> httpx.Response:
    """POST /ui/logout as the dashboard's script sends it, with ``token`` as the cookie if any."""
    headers = {**SCRIPTED, **(cookie_header(token) if token is not None else {})}
    return httpx.post(f"{api.url}/ui/logout", headers=headers)


def test_the_login_cookie_holds_a_signed_token_not_the_key(sqlite_url: str) -> None:
    settings = Settings(database_url=sqlite_url, api_keys=f"{KEY_A},{KEY_B}", session_ttl_s=600)
    with served(settings) as api:
        answer = api.client.post("/ui/login", json={"key": KEY_A})
        cookie = answer.headers["set-cookie"]
        assert KEY_A not in cookie
        assert "HttpOnly" in cookie and "SameSite=Strict" in cookie and "Max-Age=600" in cookie
        token = logged_in(api, KEY_A)
        assert token.split(".")[1] == owner_of(KEY_A)
        assert with_cookie(api, token).status_code == 200
        # the key itself is no longer a cookie the API takes
        body = assert_problem(with_cookie(api, KEY_A), 401)
        assert "not one this API accepts" in body["detail"]
        # a token whose owner, expiry or session is changed does not verify
        version, owner, expires, session_id, mac = token.split(".")
        flipped = "1" if mac[-1] == "0" else "0"  # a last digit that differs from the MAC's
        other_session = f"{int(session_id, 16) ^ 1:032x}"
        for forged in (
            f"{version}.{owner_of(KEY_B)}.{expires}.{session_id}.{mac}",
            f"{version}.{owner}.{int(expires) + 3600}.{session_id}.{mac}",
            f"{version}.{owner}.{expires}.{other_session}.{mac}",
            f"{version}.{owner}.{expires}.{session_id}.{mac[:-1]}{flipped}",
            f"{version}.{owner}.{expires}.{session_id}",
            f"{version}.{owner}.{expires}.{mac}",  # a token of the first version's shape
        ):
            assert with_cookie(api, forged).status_code == 401, forged


def test_a_token_expires_after_the_session_ttl() -> None:
    secret = b"k" * 32
    token = issue(owner_of(KEY_A), secret, now=1000.0, ttl_s=60)
    found = read_token(token, secret, now=1059.0)
    assert found is not None and found.owner == owner_of(KEY_A) and found.expires == 1060
    assert read_token(token, secret, now=1060.0) is None
    assert read_token(token, b"j" * 32, now=1010.0) is None


def test_every_login_is_a_session_of_its_own() -> None:
    secret = b"k" * 32
    tokens = {issue(owner_of(KEY_A), secret, now=1000.0, ttl_s=60) for _ in range(100)}
    found = [read_token(token, secret, now=1000.0) for token in tokens]
    assert len({session.session_id for session in found if session is not None}) == 100


@pytest.mark.parametrize(
    "token",
    [
        # a superscript two as latin-1, which str.isdigit takes and int refuses
        f"v2.a.\xb2.{SESSION_ID}.b".encode("latin-1"),
        f"v2.a.\u0661\u0662\u0663.{SESSION_ID}.b".encode(),  # Arabic-Indic digits: int reads 123
        f"v2.a.99999999999999999999999999999999999999999999.{SESSION_ID}.b".encode(),
        f"v2.a.123.{SESSION_ID}.\xb2".encode("latin-1"),  # a MAC that is not ASCII
        f"v2.\xff\xfe.123.{SESSION_ID}.b".encode("latin-1"),
        b"v2.a.123.\xb2\xb2.b",  # a session id that is not hex
        b"v2.a.123.0123456789ABCDEF0123456789ABCDEF.b",
        b"v2.a.123.0123.b",
        b"v1.a.123.b",
    ],
)
def test_a_cookie_that_is_no_token_gets_401_before_any_key_is_checked(
    sqlite_url: str, token: bytes
) -> None:
    with served(Settings(database_url=sqlite_url, api_keys=KEY_A)) as api:
        body = assert_problem(with_cookie(api, token), 401)
        assert "not one this API accepts" in body["detail"]


def test_a_token_is_accepted_only_as_it_was_issued() -> None:
    secret = b"k" * 32
    owner = owner_of(KEY_A)
    token = issue(owner, secret, now=1000.0, ttl_s=3600)
    assert read_token(token, secret, now=1000.0) is not None
    version, _, expires, session_id, mac = token.split(".")
    arabic = "".join(chr(0x660 + int(digit)) for digit in expires)  # int() reads it as expires
    for spelling in (f"0{expires}", f"00{expires}", f"+{expires}", f" {expires}", f"{expires} ",
                     arabic, f"{expires}.0", f"{expires}_"):  # fmt: skip
        respelled = f"{version}.{owner}.{spelling}.{session_id}.{mac}"
        assert read_token(respelled, secret, now=1000.0) is None, spelling
    upper = f"{version}.{owner}.{expires}.{session_id.upper()}.{mac}"
    assert read_token(upper, secret, now=1000.0) is None


def test_rotating_the_session_secret_or_removing_the_key_logs_the_browser_out(
    sqlite_url: str,
) -> None:
    keys = f"{KEY_A},{KEY_B}"
    with served(Settings(database_url=sqlite_url, api_keys=keys, session_secret=SECRET)) as api:
        token = logged_in(api, KEY_A)
        assert with_cookie(api, token).status_code == 200
    with served(Settings(database_url=sqlite_url, api_keys=keys, session_secret=SECRET)) as api:
        assert with_cookie(api, token).status_code == 200  # a restart keeps the sessions
    rotated = Settings(database_url=sqlite_url, api_keys=keys, session_secret=OTHER_SECRET)
    with served(rotated) as api:
        assert with_cookie(api, token).status_code == 401
    without_a = Settings(database_url=sqlite_url, api_keys=KEY_B, session_secret=SECRET)
    with served(without_a) as api:
        assert with_cookie(api, token).status_code == 401


def test_sessions_without_a_configured_secret_hold_across_processes_of_the_same_keys(
    sqlite_url: str,
) -> None:
    keys = f"{KEY_A},{KEY_B}"
    with served(Settings(database_url=sqlite_url, api_keys=keys)) as api:
        token = logged_in(api, KEY_B)
    with served(Settings(database_url=sqlite_url, api_keys=keys)) as api:
        assert with_cookie(api, token).status_code == 200
    other = "carol-2Mn7Bv4Cx9Zl1Kj6Hg3Fd8Sa5Qw0Ep"
    with served(Settings(database_url=sqlite_url, api_keys=f"{keys},{other}")) as api:
        assert with_cookie(api, token).status_code == 401


# -- logging out -----------------------------------------------------------------------------


def test_a_logout_ends_its_session_on_the_server_and_no_other(sqlite_url: str) -> None:
    settings = Settings(database_url=sqlite_url, api_keys=f"{KEY_A},{KEY_B}")
    with served(settings) as api:
        first, second, of_b = logged_in(api, KEY_A), logged_in(api, KEY_A), logged_in(api, KEY_B)
        assert with_cookie(api, first).status_code == 200
        answer = logged_out(api, first)
        assert answer.status_code == 204
        cleared = answer.headers["set-cookie"]
        assert cleared.startswith(f"{SESSION_COOKIE}=;") and "Max-Age=0" in cleared
        # the same cookie, replayed: refused as any token that is not genuine
        body = assert_problem(with_cookie(api, first), 401)
        assert "not one this API accepts" in body["detail"]
        page = httpx.get(
            f"{api.url}/ui/jobs", headers={**cookie_header(first), "Accept": "text/html"}
        )
        assert page.status_code == 303
        assert page.headers["location"] == "/ui/login?next=%2Fui%2Fjobs"
        # the same key's other login, another key's, and the key itself go on
        assert with_cookie(api, second).status_code == 200
        assert with_cookie(api, of_b).status_code == 200
        assert httpx.get(f"{api.url}/jobs", headers=bearer(KEY_A)).status_code == 200
    with served(settings) as api:  # a restart does not bring it back
        assert with_cookie(api, first).status_code == 401
        assert with_cookie(api, second).status_code == 200


def test_a_logout_without_a_live_session_answers_204_and_clears_the_cookie(
    sqlite_url: str,
) -> None:
    with served(Settings(database_url=sqlite_url, api_keys=KEY_A)) as api:
        token = logged_in(api, KEY_A)
        assert logged_out(api, token).status_code == 204
        forged = f"v2.{owner_of(KEY_A)}.{int(time.time()) + 600}.{SESSION_ID}.{'0' * 64}"
        for cookie in (None, token, forged, "no-token", KEY_A):
            answer = logged_out(api, cookie)
            assert answer.status_code == 204, cookie
            assert answer.headers["set-cookie"].startswith(f"{SESSION_COOKIE}=;"), cookie
        with api.store.engine.connect() as connection:
            assert connection.scalar(select(func.count()).select_from(RevokedSession)) == 1
    with served(Settings(database_url=sqlite_url)) as api:  # without keys, no session to end
        answer = logged_out(api, None)
        assert answer.status_code == 204 and "Max-Age=0" in answer.headers["set-cookie"]


def test_a_logout_another_site_may_have_forged_is_refused_and_ends_nothing(
    sqlite_url: str,
) -> None:
    with served(Settings(database_url=sqlite_url, api_keys=KEY_A)) as api:
        token = logged_in(api, KEY_A)
        foreign = {**SCRIPTED, **cookie_header(token), "Origin": "https://evil.example"}
        assert_problem(httpx.post(f"{api.url}/ui/logout", headers=foreign), 403)
        form = {**cookie_header(token), "Content-Type": "application/x-www-form-urlencoded"}
        assert_problem(httpx.post(f"{api.url}/ui/logout", headers=form, content=b"x=1"), 415)
        assert with_cookie(api, token).status_code == 200


def test_a_key_given_back_does_not_bring_back_a_session_that_logged_out(sqlite_url: str) -> None:
    both = Settings(database_url=sqlite_url, api_keys=f"{KEY_A},{KEY_B}", session_secret=SECRET)
    only_b = Settings(database_url=sqlite_url, api_keys=KEY_B, session_secret=SECRET)
    with served(both) as api:
        kept, ended = logged_in(api, KEY_A), logged_in(api, KEY_A)
    with served(only_b) as api:  # the key's removal refuses its sessions; a logout still ends one
        assert with_cookie(api, kept).status_code == 401
        assert logged_out(api, ended).status_code == 204
    with served(both) as api:
        assert with_cookie(api, kept).status_code == 200
        assert with_cookie(api, ended).status_code == 401


def test_a_logout_through_one_process_holds_in_every_other(database_url: str) -> None:
    settings = Settings(database_url=database_url, api_keys=f"{KEY_A},{KEY_B}")
    with served(settings) as one, served(settings) as other:
        token, through_other = logged_in(one, KEY_A), logged_in(other, KEY_A)
        for api in (one, other):
            assert with_cookie(api, token).status_code == 200
            assert with_cookie(api, through_other).status_code == 200
        assert logged_out(one, token).status_code == 204
        assert with_cookie(other, token).status_code == 401
        assert logged_out(other, through_other).status_code == 204
        assert with_cookie(one, through_other).status_code == 401
        assert with_cookie(one, logged_in(other, KEY_A)).status_code == 200


class CountedRevocations(RevocationStore):
    """The store's revocations, counting the look-ups and noting any made on the event loop."""

    def __init__(self, engine: Engine) -> None:
        super().__init__(engine)
        self.lookups = 0
        self.on_the_event_loop = False

    def revoked(self, session_id: str) -> bool:
        self.lookups += 1
        with contextlib.suppress(RuntimeError):  # raised where no event loop runs
            asyncio.get_running_loop()
            self.on_the_event_loop = True
        return super().revoked(session_id)


@contextmanager
def counted(settings: Settings) -> Iterator[tuple[Served, CountedRevocations]]:
    """``served``, with its revocations counted."""
    upgrade(settings.database_url)
    app = create_app(settings)
    revocations = CountedRevocations(app.state.store.engine)
    app.state.sessions.revocations = revocations
    with serve(app) as url, httpx.Client(base_url=url, timeout=30) as client:
        yield Served(url, client, app.state.store, settings), revocations


def test_only_a_request_with_a_genuine_session_cookie_looks_in_the_store(sqlite_url: str) -> None:
    with counted(Settings(database_url=sqlite_url, api_keys=KEY_A)) as (api, revocations):
        token = logged_in(api, KEY_A)
        for _ in range(3):
            assert httpx.get(f"{api.url}/jobs", headers=bearer(KEY_A)).status_code == 200
        assert httpx.get(f"{api.url}/jobs", headers=bearer(KEY_B)).status_code == 401
        assert httpx.get(f"{api.url}/jobs").status_code == 401
        assert httpx.get(f"{api.url}/healthz").status_code == 200
        forged = f"v2.{owner_of(KEY_A)}.{int(time.time()) + 600}.{SESSION_ID}.{'0' * 64}"
        for refused in ("no-token", forged):
            assert with_cookie(api, refused).status_code == 401
        assert revocations.lookups == 0
        assert with_cookie(api, token).status_code == 200
        assert revocations.lookups == 1
        assert not revocations.on_the_event_loop


def test_a_session_is_not_let_in_unchecked_while_the_store_does_not_answer(
    sqlite_url: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    def down(self: RevocationStore, session_id: str) -> bool:
        raise OperationalError("SELECT", {}, Exception("unable to open database file"))

    with served(Settings(database_url=sqlite_url, api_keys=KEY_A)) as api:
        token = logged_in(api, KEY_A)
        monkeypatch.setattr(RevocationStore, "revoked", down)
        answer = with_cookie(api, token)
        body = assert_problem(answer, 503)
        assert body["title"] == "Database unavailable" and answer.headers["retry-after"] == "1"
        assert httpx.get(f"{api.url}/version", headers=bearer(KEY_A)).status_code == 200


@pytest.mark.parametrize(
    "target",
    [
        "/\\evil.example/x",
        "//evil.example/x",
        "/\t/evil.example/x",
        "/\n/evil.example",
        "https://evil.example/",
        "javascript:alert(1)",
        "evil.example",
        "/\\\\evil.example",
        "",
    ],
)
def test_only_paths_of_this_site_are_where_a_login_returns(target: str) -> None:
    assert same_site_path(target) is None


@pytest.mark.parametrize("target", ["/", "/ui/jobs?status=queued", "/ui/jobs/7", "/docs#x"])
def test_paths_of_this_site_are_kept(target: str) -> None:
    assert same_site_path(target) == target


def test_the_login_page_sends_a_foreign_next_to_the_dashboard(sqlite_url: str) -> None:
    with served(Settings(database_url=sqlite_url, api_keys=KEY_A)) as api:
        page = api.client.get("/ui/login?next=/%5Cevil.example/x")
        assert 'data-next="/"' in page.text and "evil" not in page.text
        page = api.client.get("/ui/login?next=%2Fui%2Fjobs%3Fstatus%3Dqueued")
        assert 'data-next="/ui/jobs?status=queued"' in page.text


def test_a_key_login_still_takes_effect_at_once(sqlite_url: str) -> None:
    with served(Settings(database_url=sqlite_url, api_keys=KEY_A)) as api:
        before = time.time()
        token = logged_in(api, KEY_A)
        expires = int(token.split(".")[2])
        assert before + 8 * 3600 - 2 <= expires <= time.time() + 8 * 3600
