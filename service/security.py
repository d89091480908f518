"""Who is asking, and whether a request may go on: API keys, cross-site requests, owners.

``Guard`` is one pure ASGI middleware for the whole app. With ``NANONAV_API_KEYS`` set, every
request but ``/healthz``, the login page, its assets and the logout carries ``Authorization:
Bearer <key>``; the key is compared in constant time with every configured key, and only its
SHA-256 digest is kept: it names the request's owner. A browser may carry the dashboard's
session cookie instead (``service.sessions``); only such a request costs a look in the store,
for a logout that ended its session.
``refuse_cross_site``, a dependency of the whole app, makes a request that changes state (POST,
PUT, PATCH, DELETE) be JSON or carry a custom header, which an HTML form on another site cannot
send, and an ``Origin`` it names be this API's own (the same scheme, host and port) or an
allowed one. ``service.ids`` makes a job or study another key made answer 404, as one that does
not exist.
"""

from __future__ import annotations

import hashlib
import hmac
import logging
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Annotated, Any
from urllib.parse import quote

from fastapi import Depends, Request
from fastapi.security import HTTPBearer
from numpy.typing import NDArray
from sqlalchemy.exc import OperationalError
from starlette.datastructures import Headers
from starlette.responses import RedirectResponse
from starlette.types import ASGIApp, Receive, Scope, Send

from nanonav.settings import Settings
from nanonav.store import JobNotFound, JobStore
from nanonav.store.quotas import Quota
from service.numerals import positive_int
from service.problems import (
    PROBLEM_BASE,
    ForbiddenOrigin,
    Problem,
    UnsupportedMediaType,
    problem_response,
)
from service.sessions import SESSION_COOKIE, Sessions

logger = logging.getLogger(__name__)

# Reachable without a key: the health check, what the login page needs to show itself, and the
# logout, which ends the session its cookie names if any and always clears the cookie.
OPEN_PATHS = frozenset(
    {
        "/healthz",
        "/ui/login",
        "/ui/logout",
        "/static/app.css",
        "/static/app.js",
        "/static/favicon.svg",
        "/static/login.js",
    }
)
# The port of a URL that names none, for the schemes the API is served over.
DEFAULT_PORTS = {"http": 80, "https": 443}
# Only documents the scheme in OpenAPI: ``Guard`` has already checked the key.
BEARER = HTTPBearer(auto_error=False, description="One of the API's keys (NANONAV_API_KEYS).")
UNSAFE_METHODS = frozenset({"POST", "PUT", "PATCH", "DELETE"})
# A header a cross-site HTML form cannot send; marks a body-less write as made by a script.
SCRIPT_HEADER = "x-requested-with"


# What a page of an allowed origin (NANONAV_ALLOWED_ORIGINS) may do from a browser: the methods
# and request headers its preflight may ask for, and the answer headers its script may read.
CORS_METHODS = ("GET", "HEAD", "POST", "DELETE")
CORS_REQUEST_HEADERS = (
    "Authorization",
    "Content-Type",
    "Idempotency-Key",
    "If-None-Match",
    "Last-Event-ID",
    "X-Requested-With",
)
CORS_EXPOSED_HEADERS = (
    "ETag",
    "Location",
    "Retry-After",
    "Content-Disposition",
    "WWW-Authenticate",
)


# What the OpenAPI document says of a body-less write (a cancel, a delete): it is refused with
# 415 unless it carries this header (or declares a JSON body).
SCRIPTED_ONLY: dict[str, Any] = {
    "parameters": [
        {
            "name": "X-Requested-With",
            "in": "header",
            "required": True,
            "description": "Any value: marks the request as a script's, which an HTML form on "
            "another site cannot send (else 415). A JSON Content-Type does as well.",
            "schema": {"type": "string", "minLength": 1, "examples": ["nanonav"]},
        }
    ]
}


def owner_of(key: str) -> str:
    """What is stored of a key: its SHA-256 digest, in hex."""
    return hashlib.sha256(key.encode()).hexdigest()


@dataclass(frozen=True)
class Caller:
    """Who made a request: ``owner`` is the key's digest ('' without keys); ``scoped`` says
    whether ownership is enforced; ``quota_key`` is what its quota is counted against (the
    owner, or without keys the client's address)."""

    owner: str
    scoped: bool
    quota_key: str

    @property
    def only(self) -> str | None:
        """The owner to filter listings by, or None when every job is everyone's."""
        return self.owner if self.scoped else None


def matching_key(candidate: str, keys: tuple[str, ...]) -> bool:
    """Whether ``candidate`` is one of ``keys``, comparing with every one in constant time."""
    found = False
    for key in keys:
        found |= hmac.compare_digest(candidate.encode(), key.encode())
    return found


def presented_key(headers: Headers) -> str | None:
    """The key a request carries as a Bearer token."""
    scheme, _, token = headers.get("authorization", "").partition(" ")
    if scheme.lower() == "bearer" and token.strip():
        return token.strip()
    return None


def presented_session(headers: Headers) -> str | None:
    """The dashboard's session token, if the request carries its cookie."""
    for part in headers.get("cookie", "").split(";"):
        name, _, value = part.strip().partition("=")
        if name == SESSION_COOKIE and value:
            return value
    return None


def _problem(scope: Scope, status: int, slug: str, title: str, detail: str) -> Problem:
    return Problem(type=PROBLEM_BASE + slug, title=title, status=status, detail=detail,
                   instance=scope.get("path"))  # fmt: skip


def host_name(header: str) -> str:
    """The name a ``Host`` header gives, without its port: ``[::1]:8000`` gives ``::1``."""
    if header.startswith("["):
        return header[1:].partition("]")[0].lower()
    return header.partition(":")[0].lower()


def host_allowed(name: str, allowed: tuple[str, ...]) -> bool:
    """Whether ``name`` is one of ``allowed``: a name, ``*.parent`` for its subdomains, or ``*``."""
    for pattern in allowed:
        pattern = pattern.lower().strip("[]")
        if pattern in ("*", name) or (pattern.startswith("*.") and name.endswith(pattern[1:])):
            return True
    return False


class Guard:
    """Pure ASGI middleware: checks the ``Host`` (against DNS rebinding), authenticates the
    request and says who made it; what it refuses is a problem document like any other."""

    def __init__(self, app: ASGIApp, settings: Settings, sessions: Sessions) -> None:
        self.app = app
        self.keys = tuple(key.get_secret_value() for key in settings.api_keys)
        self.owners = frozenset(owner_of(key) for key in self.keys)
        self.sessions = sessions
        self.hosts = settings.allowed_hosts

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":  # the lifespan; the API serves no websockets
            await self.app(scope, receive, send)
            return
        headers = Headers(scope=scope)
        host = headers.get("host", "")
        if not host_allowed(host_name(host), self.hosts):
            detail = f"this API does not answer to the host {host!r}: see NANONAV_ALLOWED_HOSTS"
            problem = _problem(scope, 400, "host-not-allowed", "Host not allowed", detail)
            await problem_response(problem)(scope, receive, send)
            return
        path: str = scope["path"]
        owner = ""
        if self.keys and path not in OPEN_PATHS:
            try:
                found = await self._owner(headers)
            except OperationalError as error:
                await self._store_down(scope, error)(scope, receive, send)
                return
            if not found:
                presented = found is not None
                await self._unauthorized(scope, headers, presented)(scope, receive, send)
                return
            owner = found
        client = scope.get("client")
        address = client[0] if client else ""
        scope.setdefault("state", {})["caller"] = Caller(
            owner=owner, scoped=bool(self.keys), quota_key=owner if self.keys else address
        )
        await self.app(scope, receive, send)

    async def _owner(self, headers: Headers) -> str | None:
        """The owner a request's key or session token names; '' for one that names none,
        None when it carries neither."""
        key = presented_key(headers)
        if key is not None:
            return owner_of(key) if matching_key(key, self.keys) else ""
        token = presented_session(headers)
        if token is not None:
            found = await self.sessions.owner_of(token, self.owners, now=time.time())
            return found or ""
        return None

    def _store_down(self, scope: Scope, error: OperationalError) -> ASGIApp:
        """503, as a route answers when the store does not: a session is not let in unchecked."""
        logger.error("database error on %s %s: %s", scope["method"], scope["path"], error)
        detail = "the job store did not answer; try again shortly"
        problem = _problem(scope, 503, "database-unavailable", "Database unavailable", detail)
        return problem_response(problem, {"Retry-After": "1"})

    def _unauthorized(self, scope: Scope, headers: Headers, presented: bool) -> ASGIApp:
        """401 with a challenge; a person's browser opening a page is sent to the login page."""
        path: str = scope["path"]
        page = path == "/" or path.startswith(("/ui/", "/docs"))
        if scope["method"] == "GET" and page and "text/html" in headers.get("accept", ""):
            query = scope.get("query_string", b"").decode("latin-1")
            target = path + (f"?{query}" if query else "")
            return RedirectResponse(f"/ui/login?next={quote(target, safe='')}", status_code=303)
        challenge = 'Bearer realm="nanonav"'
        detail = "this API needs a key: send 'Authorization: Bearer <key>'"
        if presented:
            challenge += ', error="invalid_token"'
            detail = "the key sent is not one this API accepts"
        problem = _problem(scope, 401, "unauthorized", "Unauthorized", detail)
        return problem_response(problem, {"WWW-Authenticate": challenge})


async def refuse_cross_site(request: Request) -> None:
    """A write another site may have forged is refused: one from a foreign ``Origin`` with 403,
    one neither JSON nor marked by ``X-Requested-With`` (as an HTML form's) with 415. A
    dependency of the whole app, so a method a path does not take still gets its 405; ``async``
    because it waits on nothing, and a plain ``def`` would cost every request a thread hop."""
    if request.method not in UNSAFE_METHODS:
        return
    headers = request.headers
    origin = headers.get("origin")
    if origin is not None and not _own_origin(origin.lower(), headers, request):
        raise ForbiddenOrigin(f"requests from origin {origin!r} may not change anything here")
    media = headers.get("content-type", "").split(";")[0].strip().lower()
    kind, _, subtype = media.partition("/")
    json = kind == "application" and (subtype == "json" or subtype.endswith("+json"))
    if not json and not headers.get(SCRIPT_HEADER):
        raise UnsupportedMediaType(
            f"a {request.method} must be application/json (it is {media or 'undeclared'}) or "
            "carry an X-Requested-With header"
        )


def _own_origin(origin: str, headers: Headers, request: Request) -> bool:
    """Whether ``origin`` (lower case) is an allowed one, or this API's own: the scheme the
    request came by (``X-Forwarded-Proto`` of a proxy uvicorn trusts), the host and the port
    of its ``Host``, a port left out being the scheme's default."""
    settings: Settings = request.app.state.settings
    if origin in settings.allowed_origins:
        return True
    scheme, separator, authority = origin.partition("://")
    own = request.url.scheme.lower()
    if not separator or scheme != own:
        return False
    site = site_of(authority, scheme)
    return site is not None and site == site_of(headers.get("host", "").lower(), own)


def site_of(authority: str, scheme: str) -> tuple[str, int] | None:
    """The host and port an Origin's or a ``Host``'s ``authority`` names (``host``,
    ``host:8000``, ``[::1]:8000``), the port defaulting to the scheme's; None if it names no
    host, or a port that is not one written plainly."""
    if authority.startswith("["):
        inside, closed, after = authority[1:].partition("]")
        if not closed or after[:1] not in {"", ":"}:
            return None
        host, port = f"[{inside}]", after[1:]
    else:
        host, _, port = authority.partition(":")
    number = positive_int(port, maximum=65535) if port else DEFAULT_PORTS.get(scheme)
    if not host or number is None:
        return None
    return host, number


def caller_of(request: Request) -> Caller:
    """Who made ``request``, as ``Guard`` found it."""
    caller = request.scope.get("state", {}).get("caller")
    if isinstance(caller, Caller):
        return caller
    return Caller(owner="", scoped=False, quota_key="")


async def _caller(request: Request) -> Caller:
    # ``async``: as a plain ``def``, a dependency costs every request a thread-pool hop.
    return caller_of(request)


CallerDep = Annotated[Caller, Depends(_caller)]


def owned_tables(store: JobStore, caller: Caller) -> Callable[[int], dict[str, NDArray[Any]]]:
    """The Q-table reader ``policy_from`` checks use: another key's job is not there."""

    def read(job_id: int) -> dict[str, NDArray[Any]]:
        if caller.scoped and store.owner_of(job_id) != caller.owner:
            raise JobNotFound(job_id)
        return store.qtable(job_id)

    return read


def quota_of(caller: Caller, settings: Settings) -> Quota:
    """The quota a submit by ``caller`` counts against."""
    return Quota(caller.quota_key, settings.quota_active_jobs, settings.quota_robot_steps)
