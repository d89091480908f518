"""Webhooks: which callback URLs a server may call, how a delivery is signed and checked, and
how long a failed one waits before the next try.

A delivery is a JSON ``POST`` with the header ``NanoNav-Signature: t=<unix seconds>,v1=<hex>``,
where ``<hex>`` is HMAC-SHA256 under the server's secret of ``"<t>." + body``. The timestamp
is signed with the body, so a receiver that also refuses old timestamps (``verify`` does,
past ``tolerance_s``) cannot be fooled by a replayed delivery.
"""

from __future__ import annotations

import hashlib
import hmac
import time
from collections.abc import Sequence
from urllib.parse import urlsplit

SIGNATURE_HEADER = "NanoNav-Signature"
EVENT_HEADER = "NanoNav-Event"
DELIVERY_HEADER = "NanoNav-Delivery"
MAX_URL_LENGTH = 2048
# A retry waits RETRY_BASE_S x 2^(attempts - 1), at most RETRY_CAP_S.
RETRY_CAP_S = 3600.0


class SignatureMismatch(ValueError):
    """A delivery whose signature header is missing, malformed, stale or wrong."""


def signature(secret: str, body: bytes, timestamp: int) -> str:
    """The value of the signature header for ``body`` sent at ``timestamp``."""
    mac = hmac.new(secret.encode(), f"{timestamp}.".encode() + body, hashlib.sha256)
    return f"t={timestamp},v1={mac.hexdigest()}"


def verify(
    secret: str,
    header: str | None,
    body: bytes,
    *,
    tolerance_s: float = 300.0,
    now: float | None = None,
) -> int:
    """The timestamp of a delivery whose signature is right and recent; ``SignatureMismatch``
    otherwise. What a receiver calls with the raw body, before parsing it."""
    if not header:
        raise SignatureMismatch(f"no {SIGNATURE_HEADER} header")
    parts = dict(item.split("=", 1) for item in header.split(",") if "=" in item)
    try:
        timestamp = int(parts["t"])
        given = parts["v1"]
    except (KeyError, ValueError):
        raise SignatureMismatch(f"not a {SIGNATURE_HEADER} header: {header!r}") from None
    clock = time.time() if now is None else now
    if abs(clock - timestamp) > tolerance_s:
        raise SignatureMismatch(f"the timestamp {timestamp} is over {tolerance_s:g} s away")
    expected = signature(secret, body, timestamp).split("v1=", 1)[1]
    if not hmac.compare_digest(expected, given):
        raise SignatureMismatch("the signature does not match the body")
    return timestamp


def refusal(url: str, allowed_hosts: Sequence[str]) -> str | None:
    """Why this server will not call ``url``, or None if it may.

    ``allowed_hosts`` holds host names, each matched exactly (``hooks.example.org``) or with
    its subdomains (``*.example.org``); a port may follow (``localhost:9000``) to allow only
    that port."""
    if not allowed_hosts:
        return "this server sends no webhooks (NANONAV_WEBHOOK_HOSTS is empty)"
    if len(url) > MAX_URL_LENGTH:
        return f"longer than {MAX_URL_LENGTH} characters"
    try:
        parts = urlsplit(url)
        port = parts.port
    except ValueError as error:
        return f"not a URL: {error}"
    if parts.scheme not in {"http", "https"}:
        return "not an http:// or https:// URL"
    if parts.username is not None or parts.password is not None:
        return "a callback URL may not carry a user name or password"
    host = (parts.hostname or "").rstrip(".").lower()
    if not host:
        return "the URL names no host"
    if parts.fragment:
        return "a callback URL may not have a #fragment"
    if not any(_matches(host, port, pattern) for pattern in allowed_hosts):
        return f"the host {host!r} is not among the hosts this server may call"
    return None


def _matches(host: str, port: int | None, pattern: str) -> bool:
    name, _, only_port = pattern.lower().partition(":")
    if only_port and port != int(only_port):
        return False
    if name.startswith("*."):
        return host.endswith(name[1:])
    return host == name


def retry_delay_s(attempts: int, base_s: float) -> float:
    """How long to wait after the ``attempts``-th failed try: doubling, at most an hour."""
    return float(min(base_s * 2 ** max(attempts - 1, 0), RETRY_CAP_S))
