"""The dashboard's login: a signed session token in a cookie, never the API key itself.

A person who logs in with a key gets ``v2.<owner>.<expires>.<session id>.<mac>``: the key's
owner (its SHA-256 digest, which is what the store keeps), when the token stops being accepted
(Unix seconds), a random id of this login, and an HMAC-SHA256 of the three under the session
secret. A stolen cookie therefore opens the dashboard until it expires or its session ends, and
never yields the key. A logout ends the session on the server: its id is kept in the store
(``nanonav.store.revocations``) until the token would have expired, and every API process of
the deployment refuses the token from then on, while the same key's other logins go on. Every
token is revoked at once by rotating ``NANONAV_SESSION_SECRET``; the tokens of one key, by
removing that key from ``NANONAV_API_KEYS`` (a token is accepted only for an owner whose key is
still configured). Tokens of the first version (``v1.``, with no session id) are refused.
"""

from __future__ import annotations

import hashlib
import hmac
import secrets
import string
from collections.abc import Collection
from dataclasses import dataclass
from datetime import UTC, datetime
from urllib.parse import urlsplit

from fastapi.concurrency import run_in_threadpool

from nanonav.settings import Settings
from nanonav.store.revocations import RevocationStore
from service.numerals import positive_int

SESSION_COOKIE = "nanonav_session"
VERSION = "v2"
# A session id: this many random bytes, in lower-case hex.
SESSION_ID_BYTES = 16
HEX_DIGITS = frozenset(string.digits + "abcdef")


def session_secret(settings: Settings) -> bytes:
    """The key tokens are signed with: the configured secret, or else one derived from the API
    keys, so that every API process of a deployment agrees without being told."""
    if settings.session_secret is not None:
        return settings.session_secret.get_secret_value().encode()
    keys = sorted(key.get_secret_value() for key in settings.api_keys)
    return hashlib.sha256(b"nanonav-session\0" + "\0".join(keys).encode()).digest()


@dataclass(frozen=True)
class SessionToken:
    """What a genuine token says: whose session it is, until when (Unix seconds), and which
    login it is (``session_id``, what a logout revokes)."""

    owner: str
    expires: int
    session_id: str


def _mac(secret: bytes, owner: str, expires: int, session_id: str) -> str:
    message = f"{VERSION}.{owner}.{expires}.{session_id}".encode()
    return hmac.new(secret, message, hashlib.sha256).hexdigest()


def issue(owner: str, secret: bytes, *, now: float, ttl_s: float) -> str:
    """A token for a new session of ``owner``, accepted for ``ttl_s`` seconds from ``now``
    unless it is revoked first."""
    expires = int(now + ttl_s)
    session_id = secrets.token_hex(SESSION_ID_BYTES)
    mac = _mac(secret, owner, expires, session_id)
    return f"{VERSION}.{owner}.{expires}.{session_id}.{mac}"


def read_token(token: str, secret: bytes, *, now: float) -> SessionToken | None:
    """What ``token`` says if it is genuine (issued under ``secret``, as it was issued) and
    unexpired; else None. Whether its key is still configured, and whether a logout revoked
    it, are not looked at here."""
    parts = token.split(".")
    if len(parts) != 5 or parts[0] != VERSION:
        return None
    _, owner, expires_text, session_id, given = parts
    # Only the spelling the token was issued with: "0123" would verify under the MAC of 123.
    expires = positive_int(expires_text)
    if expires is None or not given.isascii():  # compare_digest refuses other text
        return None
    if len(session_id) != 2 * SESSION_ID_BYTES or not set(session_id) <= HEX_DIGITS:
        return None
    if not hmac.compare_digest(_mac(secret, owner, expires, session_id), given):
        return None
    if expires <= now:
        return None
    return SessionToken(owner=owner, expires=expires, session_id=session_id)


class Sessions:
    """The dashboard's sessions as one API process sees them: issued and read under the
    deployment's secret, ended in the store that every process shares."""

    def __init__(self, settings: Settings, revocations: RevocationStore) -> None:
        self.secret = session_secret(settings)
        self.ttl_s = settings.session_ttl_s
        self.revocations = revocations

    def issue(self, owner: str, *, now: float) -> str:
        """A token for a new session of ``owner``."""
        return issue(owner, self.secret, now=now, ttl_s=self.ttl_s)

    async def owner_of(self, token: str, owners: Collection[str], *, now: float) -> str | None:
        """The owner whose session ``token`` is, if it is genuine, unexpired, for one of
        ``owners`` (whose keys are configured) and not ended by a logout. Only a token that
        passes the rest costs a query, on the thread pool: the event loop never waits on it."""
        found = read_token(token, self.secret, now=now)
        if found is None or found.owner not in owners:
            return None
        if await run_in_threadpool(self.revocations.revoked, found.session_id):
            return None
        return found.owner

    def end(self, token: str, *, now: float) -> bool:
        """End the session of ``token`` in every process (and forget sessions long expired);
        False, and nothing done, for a token that is not genuine or has expired already."""
        found = read_token(token, self.secret, now=now)
        if found is None:
            return False
        self.revocations.revoke(
            found.session_id,
            expires_at=datetime.fromtimestamp(found.expires, UTC),
            now=datetime.fromtimestamp(now, UTC),
        )
        return True


def session_cookie(token: str, *, secure: bool, max_age_s: float) -> str:
    """The Set-Cookie value that keeps ``token`` for the dashboard: HttpOnly (no script reads
    it), SameSite=Strict (no other site's request carries it), gone when it expires."""
    flags = "; Secure" if secure else ""
    return (
        f"{SESSION_COOKIE}={token}; Path=/; Max-Age={int(max_age_s)}; HttpOnly; "
        f"SameSite=Strict{flags}"
    )


def cleared_cookie() -> str:
    """The Set-Cookie value that makes the browser forget its session."""
    return f"{SESSION_COOKIE}=; Path=/; Max-Age=0; HttpOnly; SameSite=Strict"


def same_site_path(target: str) -> str | None:
    """``target`` if a browser sent there stays on this site, else None.

    A path only: one leading ``/`` and not two, no backslash (browsers read ``/\\host`` as
    ``//host``), no control character or space (browsers drop tabs and line breaks, so
    ``/\\t/host`` becomes ``//host``), no scheme or host."""
    if not target.startswith("/") or target.startswith("//"):
        return None
    if "\\" in target or any(ord(char) <= 0x20 or ord(char) == 0x7F for char in target):
        return None
    parts = urlsplit(target)
    if parts.scheme or parts.netloc:
        return None
    return target
