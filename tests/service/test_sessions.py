"""The dashboard's login: a signed, expiring session token in the cookie instead of the key, and
a page that only ever sends a person back to a path of this site."""

from __future__ import annotations

import re
import time

import httpx
import pytest

from nanonav.settings import Settings
from service.security import owner_of
from service.sessions import SESSION_COOKIE, issue, owner_of_token, same_site_path
from tests.service.test_api import assert_problem
from tests.service.test_security import KEY_A, KEY_B, Served, served

SECRET = "s3ss10n-9Qw2Er7Ty4Ui1Op6As3Df8Gh5Jk"
OTHER_SECRET = "r0tat3d-5Zx8Cv1Bn6Mq3Wr9Et2Yu7Io4Pa"


def logged_in(api: Served, key: str) -> str:
    """Log in with ``key``; the cookie's value."""
    answer = api.client.post("/ui/login", json={"key": key})
    assert answer.status_code == 204, answer.text
    match = re.match(rf"{SESSION_COOKIE}=([^;]+);", answer.headers["set-cookie"])
    assert match is not None
    return match.group(1)


def with_cookie(api: Served, token: str | bytes) -> httpx.Response:
    """GET /jobs with ``token`` as the session cookie; bytes are sent as they are."""
    raw = token if isinstance(token, bytes) else token.encode()
    return httpx.get(f"{api.url}/jobs", headers={"Cookie": SESSION_COOKIE.encode() + b"=" + raw})


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
        # a token whose owner or expiry is changed does not verify
        version, owner, expires, mac = token.split(".")
        flipped = "1" if mac[-1] == "0" else "0"  # a last digit that differs from the MAC's
        for forged in (
            f"{version}.{owner_of(KEY_B)}.{expires}.{mac}",
            f"{version}.{owner}.{int(expires) + 3600}.{mac}",
            f"{version}.{owner}.{expires}.{mac[:-1]}{flipped}",
            f"{version}.{owner}.{expires}",
        ):
            assert with_cookie(api, forged).status_code == 401, forged


def test_a_token_expires_after_the_session_ttl() -> None:
    secret = b"k" * 32
    owners = {owner_of(KEY_A)}
    token = issue(owner_of(KEY_A), secret, now=1000.0, ttl_s=60)
    assert owner_of_token(token, secret, owners, now=1059.0) == owner_of(KEY_A)
    assert owner_of_token(token, secret, owners, now=1060.0) is None
    assert owner_of_token(token, b"j" * 32, owners, now=1010.0) is None


@pytest.mark.parametrize(
    "token",
    [
        b"v1.a.\xb2.b",  # a superscript two as latin-1, which str.isdigit takes and int refuses
        "v1.a.\u0661\u0662\u0663.b".encode(),  # Arabic-Indic digits, which int reads as 123
        b"v1.a.99999999999999999999999999999999999999999999.b",
        b"v1.a.123.\xb2",  # a MAC that is not ASCII
        b"v1.\xff\xfe.123.b",
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
    assert owner_of_token(token, secret, {owner}, now=1000.0) == owner
    version, _, expires, mac = token.split(".")
    arabic = "".join(chr(0x660 + int(digit)) for digit in expires)  # int() reads it as expires
    for spelling in (f"0{expires}", f"00{expires}", f"+{expires}", f" {expires}", f"{expires} ",
                     arabic, f"{expires}.0", f"{expires}_"):  # fmt: skip
        respelled = f"{version}.{owner}.{spelling}.{mac}"
        assert owner_of_token(respelled, secret, {owner}, now=1000.0) is None, spelling


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
