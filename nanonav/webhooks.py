"""Webhooks: which callback URLs and addresses a server may call, how a delivery is signed and
checked, and how long a failed one waits before the next try.

A delivery is a JSON ``POST`` with the header ``NanoNav-Signature: t=<unix seconds>,v1=<hex>``,
where ``<hex>`` is HMAC-SHA256 under the server's secret of ``"<t>." + body``. The timestamp
is signed with the body, so a receiver that also refuses old timestamps (``verify`` does,
past ``tolerance_s``) cannot be fooled by a replayed delivery.

A callback URL is checked with the parser that sends it (httpx's), at submit and again at
send time, and kept in the form it is sent in; a URL that parser would refuse or that could
not be resolved (an empty label, a control character, a name IDNA refuses) is refused up
front, not left to fail inside the sender. The host names in the allow-list say whom the
server may call; the addresses those names resolve to, checked at send time, say where:
only public addresses, unless the operator allows others by address or network.
"""

from __future__ import annotations

import hashlib
import hmac
import ipaddress
import re
import time
from collections.abc import Sequence

import httpx

SIGNATURE_HEADER = "NanoNav-Signature"
EVENT_HEADER = "NanoNav-Event"
DELIVERY_HEADER = "NanoNav-Delivery"
MAX_URL_LENGTH = 2048
# A retry waits RETRY_BASE_S x 2^(attempts - 1), at most RETRY_CAP_S.
RETRY_CAP_S = 3600.0
# A DNS name as a resolver takes it (RFC 1035, with the underscore some hosts carry).
LABEL = re.compile(r"[a-z0-9_](?:[a-z0-9_-]*[a-z0-9_])?")

Address = ipaddress.IPv4Address | ipaddress.IPv6Address
Network = ipaddress.IPv4Network | ipaddress.IPv6Network
# Where cloud providers serve instance credentials: AWS, GCP, Azure, OpenStack and
# DigitalOcean (169.254.169.254, and AWS's IPv6 fd00:ec2::254), AWS ECS and EKS (169.254.170.2,
# .23 and fd00:ec2::23), Alibaba (100.100.100.200), Oracle (192.0.0.192). A network the
# operator allows never opens these; only an entry naming the address alone does.
METADATA_ADDRESSES = frozenset(
    ipaddress.ip_address(a)
    for a in ("169.254.169.254", "169.254.170.2", "169.254.170.23", "fd00:ec2::254",
              "fd00:ec2::23", "100.100.100.200", "192.0.0.192")
)  # fmt: skip
# IPv6 addresses that carry an IPv4 address in their low 32 bits. A connection to an
# IPv4-mapped one, or to one of NAT64's well-known prefix (RFC 6052), reaches the IPv4 address
# alone; the IPv4-compatible (RFC 4291, deprecated; not :: and ::1) and IPv4-translated
# (RFC 2765) forms are IPv6 addresses of their own as well.
MAPPED = ipaddress.IPv6Network("::ffff:0:0/96")
NAT64 = ipaddress.IPv6Network("64:ff9b::/96")
COMPATIBLE = ipaddress.IPv6Network("::/96")
TRANSLATED = ipaddress.IPv6Network("::ffff:0:0:0/96")


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


class Refused(ValueError):
    """A callback URL or address this server will not call; the message says why."""


def refusal(url: str, allowed_hosts: Sequence[str]) -> str | None:
    """Why this server will not call ``url``, or None if it may."""
    try:
        callback_target(url, allowed_hosts)
    except Refused as why:
        return str(why)
    return None


def callback_target(url: str, allowed_hosts: Sequence[str]) -> httpx.URL:
    """``url`` as the sender sends it, if the allow-list permits its host; ``Refused`` if not.

    ``allowed_hosts`` holds host names, each matched exactly (``hooks.example.org``) or with
    its subdomains (``*.example.org``); a port may follow (``localhost:9000``) to allow only
    that port. A name is matched in its ASCII (``xn--``) form, without a final dot."""
    if not allowed_hosts:
        raise Refused("this server sends no webhooks (NANONAV_WEBHOOK_HOSTS is empty)")
    target = parsed(url)
    host = target.raw_host.decode("ascii").rstrip(".")
    if not any(_matches(host, target.port, pattern) for pattern in allowed_hosts):
        raise Refused(f"the host {host!r} is not among the hosts this server may call")
    return target


def normalised(url: str) -> str:
    """``url`` in the form the sender sends it (the host lower-case and IDNA-encoded, the
    port without a default or leading zeros, the path percent-encoded and without dot
    segments): what a delivery stores and a client reads back. ``Refused`` if it is not a
    URL this server could send to."""
    return str(parsed(url))


def parsed(url: str) -> httpx.URL:
    """``url`` parsed as httpx parses it to send it, if the sender could send to it at all;
    ``Refused`` with the reason otherwise. Says nothing of whether the host is allowed."""
    if len(url) > MAX_URL_LENGTH:
        raise Refused(f"longer than {MAX_URL_LENGTH} characters")
    # Other parsers drop tabs and newlines, or take a space for the end of the URL.
    strange = next((c for c in url if c.isspace() or not c.isprintable()), None)
    if strange is not None:
        raise Refused(f"a callback URL may not hold a control character or space ({strange!r})")
    try:
        target = httpx.URL(url)
        port = target.port
    except (httpx.InvalidURL, ValueError) as error:  # IDNA's errors are UnicodeErrors
        raise Refused(f"not a URL: {error}") from None
    if target.scheme not in {"http", "https"}:
        raise Refused("not an http:// or https:// URL")
    if target.userinfo:
        raise Refused("a callback URL may not carry a user name or password")
    if target.fragment:
        raise Refused("a callback URL may not have a #fragment")
    if port is not None and not 0 < port < 65536:
        raise Refused(f"{port} is not a port")
    _check_host(target.raw_host.decode("ascii"))
    if len(str(target)) > MAX_URL_LENGTH:
        raise Refused(f"longer than {MAX_URL_LENGTH} characters once encoded as it is sent")
    return target


def _check_host(host: str) -> None:
    """An address, or a name every label of which a resolver takes (one final dot allowed)."""
    if not host:
        raise Refused("the URL names no host")
    if host_address(host) is not None:
        return
    name = host.removesuffix(".")
    labels = name.split(".")
    if "" in labels:
        raise Refused(f"the host name {host!r} has an empty label")
    for label in labels:
        if len(label) > 63:
            raise Refused(f"the host name {host!r} has a label longer than 63 characters")
        if not LABEL.fullmatch(label):
            raise Refused(f"{host!r} is not a DNS name (letters, digits, '-' and '_')")
    if len(name) > 253:
        raise Refused(f"the host name {host!r} is longer than 253 characters")


def host_address(host: str) -> Address | None:
    """The address a URL's host is written as (``127.0.0.1``, ``::1``), or None for a name."""
    try:
        return ipaddress.ip_address(host)
    except ValueError:
        return None


def _matches(host: str, port: int | None, pattern: str) -> bool:
    name, _, only_port = pattern.lower().partition(":")
    if only_port and port != int(only_port):
        return False
    if name.startswith("*."):
        return host.endswith(name[1:])
    return host == name


def address_refusal(address: str | Address, allowed: Sequence[Network]) -> str | None:
    """Why this server will not connect to ``address``, or None if it may.

    A public address may be called. Any other (loopback, private, link-local, site-local,
    unspecified, multicast, reserved, shared) only if a network in ``allowed`` holds it; a cloud
    metadata address only if an entry of ``allowed`` is that address alone. An IPv6 address
    that carries an IPv4 one (IPv4-mapped, -compatible or -translated, NAT64, 6to4, Teredo's
    server and client) passes only if the IPv4 address does too: ``::/0`` opens none of them."""
    ip = ipaddress.ip_address(address) if isinstance(address, str) else address
    reached = _reached(ip)
    for each in reached:
        if each in METADATA_ADDRESSES and not any(
            net.num_addresses == 1 and each in net for net in allowed
        ):
            return _refused("a cloud metadata address")
    for each in reached:
        kind = _kind(each)
        if kind is not None and not any(each in net for net in allowed):
            return _refused(kind)
    return None


def _reached(ip: Address) -> tuple[Address, ...]:
    """The addresses a connection to ``ip`` reaches: the IPv4 address an IPv4-mapped or NAT64
    address stands for; the IPv4 address it carries and ``ip`` for an IPv4-compatible or
    -translated one, a 6to4 one (its router's) and a Teredo one (its server's and client's);
    else ``ip``."""
    if isinstance(ip, ipaddress.IPv4Address):
        return (ip,)
    carried = ipaddress.IPv4Address(int(ip) & 0xFFFFFFFF)
    if ip in MAPPED or ip in NAT64:
        return (carried,)
    if (ip in COMPATIBLE and int(ip) > 1) or ip in TRANSLATED:
        return (carried, ip)
    if ip.sixtofour is not None:
        return (ip.sixtofour, ip)
    if ip.teredo is not None:
        return (*ip.teredo, ip)
    return (ip,)


def _kind(ip: Address) -> str | None:
    """What kind of address that is not public ``ip`` is, or None if it is public."""
    if ip in METADATA_ADDRESSES:
        return "a cloud metadata address"
    checks = (
        (ip.is_loopback, "a loopback address"),
        (ip.is_unspecified, "the unspecified address"),
        (ip.is_link_local, "a link-local address"),
        (isinstance(ip, ipaddress.IPv6Address) and ip.is_site_local, "a site-local address"),
        (ip.is_multicast, "a multicast address"),
        (ip.is_reserved, "a reserved address"),
        (ip.is_private, "a private address"),
        (not ip.is_global, "not a public address"),
    )
    return next((kind for matched, kind in checks if matched), None)


def _refused(kind: str) -> str:
    return f"{kind} (NANONAV_WEBHOOK_ADDRESSES may allow it)"


def retry_delay_s(attempts: int, base_s: float) -> float:
    """How long to wait after the ``attempts``-th failed try: doubling, at most an hour."""
    return float(min(base_s * 2 ** max(attempts - 1, 0), RETRY_CAP_S))
