"""The dashboard's login: a signed session token in a cookie, never the API key itself.

A person who logs in with a key gets ``v1.<owner>.<expires>.<mac>``: the key's owner (its
SHA-256 digest, which is what the store keeps), when the token stops being accepted (Unix
seconds), and an HMAC-SHA256 of the two under the session secret. A stolen cookie therefore
opens the dashboard until it expires, and never yields the key. Every token is revoked at once
by rotating ``NANONAV_SESSION_SECRET``; the tokens of one key, by removing that key from
``NANONAV_API_KEYS`` (a token is accepted only for an owner whose key is still configured).
"""

from __future__ import annotations

import hashlib
import hmac
from collections.abc import Collection
from urllib.parse import urlsplit

from nanonav.settings import Settings
from service.numerals import positive_int

SESSION_COOKIE = "nanonav_session"
VERSION = "v1"


def session_secret(settings: Settings) -> bytes:
    """The key tokens are signed with: the configured secret, or else one derived from the API
    keys, so that every API process of a deployment agrees without being told."""
    if settings.session_secret is not None:
        return settings.session_secret.get_secret_value().encode()
    keys = sorted(key.get_secret_value() for key in settings.api_keys)
    return hashlib.sha256(b"nanonav-session\0" + "\0".join(keys).encode()).digest()


def _mac(secret: bytes, owner: str, expires: int) -> str:
    message = f"{VERSION}.{owner}.{expires}".encode()
    return hmac.new(secret, message, hashlib.sha256).hexdigest()


def issue(owner: str, secret: bytes, *, now: float, ttl_s: float) -> str:
    """A token for ``owner`` that is accepted for ``ttl_s`` seconds from ``now``."""
    expires = int(now + ttl_s)
    return f"{VERSION}.{owner}.{expires}.{_mac(secret, owner, expires)}"


def owner_of_token(token: str, secret: bytes, owners: Collection[str], *, now: float) -> str | None:
    """The owner a token names if it is genuine, unexpired and its key still configured."""
    parts = token.split(".")
    if len(parts) != 4 or parts[0] != VERSION:
        return None
    _, owner, expires_text, given = parts
    # Only the spelling the token was issued with: "0123" would verify under the MAC of 123.
    expires = positive_int(expires_text)
    if expires is None or not given.isascii():  # compare_digest refuses other text
        return None
    if not hmac.compare_digest(_mac(secret, owner, expires), given):
        return None
    if expires <= now or owner not in owners:
        return None
    return owner


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
