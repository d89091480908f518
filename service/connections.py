"""Bounded connections: how many one API process serves, and how long a request's head and body
may take to arrive.

uvicorn bounds neither: ``timeout_keep_alive`` covers only the wait between two requests, and
``limit_concurrency`` refuses with no room kept for a health check. A client that sent a header
line every few seconds, or its body a byte at a time, held its connection as long as it liked,
and enough of them used up the process's open files. This is uvicorn's ``httptools`` protocol
with three additions:

- the request head must arrive within ``header_timeout_s`` of the connection (or, on a kept-alive
  one, of the next request's first byte), else 408 and the connection is closed;
- the body must arrive within ``body_timeout_s`` of the head, else 408 (if nothing was answered
  yet) and the connection is closed;
- ``max_connections`` are served. Past them a new connection takes the place of the one idle
  longest (waiting for a request head, its first or its next, for a second or more), so that
  slow clients cannot keep others out; when none is idle, ``healthz_connections`` more answer
  ``/healthz`` alone, once each, and 503 to anything else, and past those a new connection is
  closed at once.
"""

from __future__ import annotations

import asyncio
import itertools
import resource
from asyncio import TimerHandle
from dataclasses import dataclass
from typing import Any, cast

import httptools
import uvicorn
from starlette.types import ASGIApp
from uvicorn._types import ASGIReceiveCallable, ASGISendCallable, Scope
from uvicorn.protocols.http.httptools_impl import STATUS_LINE, HttpToolsProtocol
from uvicorn.server import ServerState

from nanonav.settings import Settings, get_settings
from service.problems import PROBLEM_BASE, PROBLEM_JSON, Problem, problem_response

HEALTH_PATH = b"/healthz"
# Files an API process holds besides its clients' connections: the store's pool (up to 15),
# the SQLite file and its journal, the listening socket, logs, pictures and static files being
# read, the interpreter's own; what is left of the open-file limit must hold the connections.
OWN_FILES = 128
# How long a client refused for want of connections is asked to wait, seconds.
BUSY_RETRY_AFTER_S = 1
# How long a connection must have waited for a request head before a new one may take its
# place, seconds: a slow client has waited longer; one that connected in the same burst has not.
GIVES_WAY_AFTER_S = 1.0
# The order in which connections began to wait: many begin in one turn of the loop, at one time.
_WAITING = itertools.count()


class OpenFilesTooFew(Exception):
    """The connection limits do not fit the open files this process may have."""


@dataclass(frozen=True)
class ConnectionLimits:
    """What one API process grants its clients, from the settings of the same names."""

    max_connections: int
    healthz_connections: int
    header_timeout_s: float
    body_timeout_s: float

    @classmethod
    def of(cls, settings: Settings) -> ConnectionLimits:
        return cls(
            max_connections=settings.api_max_connections,
            healthz_connections=settings.api_healthz_connections,
            header_timeout_s=settings.api_header_timeout_s,
            body_timeout_s=settings.api_body_timeout_s,
        )

    @property
    def open_files(self) -> int:
        """The open files the process needs at most, its own included."""
        return self.max_connections + self.healthz_connections + OWN_FILES


def fit_open_files(limits: ConnectionLimits) -> None:
    """Raise the soft open-file limit to what ``limits`` need if the hard one allows it (its
    children inherit it), else refuse: past the limit ``accept`` fails, and so do the store's
    connections and every file the API opens, ``/healthz`` included."""
    soft, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
    needed = limits.open_files
    if soft == resource.RLIM_INFINITY or soft >= needed:
        return
    if hard == resource.RLIM_INFINITY or hard >= needed:
        resource.setrlimit(resource.RLIMIT_NOFILE, (needed, hard))
        return
    raise OpenFilesTooFew(
        f"NANONAV_API_MAX_CONNECTIONS ({limits.max_connections}) and "
        f"NANONAV_API_HEALTHZ_CONNECTIONS ({limits.healthz_connections}) need {needed} open "
        f"files with the {OWN_FILES} the API keeps for itself, but this process may open at "
        f"most {hard} (`ulimit -n`): lower them, or raise the limit"
    )


class BoundedConfig(uvicorn.Config):
    """uvicorn's configuration, serving with :class:`BoundedHttpToolsProtocol` under ``limits``
    (the API serves no websockets, so no upgrade is taken either)."""

    def __init__(self, app: Any, *, limits: ConnectionLimits, **options: Any) -> None:
        super().__init__(app, http=BoundedHttpToolsProtocol, ws="none", **options)
        self.limits = limits


class BoundedHttpToolsProtocol(HttpToolsProtocol):
    """One connection, bounded in time while its client sends, and counted against the others
    of its server (``server_state.connections``)."""

    def __init__(
        self,
        config: uvicorn.Config,
        server_state: ServerState,
        app_state: dict[str, Any],
        _loop: asyncio.AbstractEventLoop | None = None,
    ) -> None:
        super().__init__(config, server_state, app_state, _loop)
        # Started by hand (`uvicorn --http service.connections:BoundedHttpToolsProtocol`), the
        # environment's settings apply.
        self.limits = (
            config.limits
            if isinstance(config, BoundedConfig)
            else ConnectionLimits.of(get_settings())
        )
        self.admitted = False  # one of the max_connections, not of the /healthz reserve
        self.idle_since: float | None = None  # when it began waiting for a request head
        self.waiting = 0  # its place in the order connections began waiting in
        self.began = False  # whether a byte of the request waited for has arrived
        self._deadline: TimerHandle | None = None

    def connection_made(self, transport: asyncio.Transport) -> None:  # type: ignore[override]
        super().connection_made(transport)
        self._wait()
        limits = self.limits
        count = len(self.connections)
        if count > limits.max_connections:
            # those closed a moment ago are still counted until the loop reports them lost
            count = sum(not other.transport.is_closing() for other in self.connections)
            if count > limits.max_connections and self._make_room():
                count -= 1
        self.admitted = count <= limits.max_connections
        if count > limits.max_connections + limits.healthz_connections:
            transport.close()
            return
        self._arm(limits.header_timeout_s, self._head_late)

    def connection_lost(self, exc: Exception | None) -> None:
        self._disarm()
        self.idle_since = None
        super().connection_lost(exc)

    def on_message_begin(self) -> None:
        super().on_message_begin()
        self.began = True
        if self._deadline is None:  # a kept-alive connection's next request: its own time
            self._arm(self.limits.header_timeout_s, self._head_late)

    def on_headers_complete(self) -> None:
        self._disarm()
        self.idle_since = None
        self.began = False
        limits = self.limits
        if not self.admitted and len(self.connections) <= limits.max_connections:
            self.admitted = True
        app = self.app
        if not self.admitted and self._path() != HEALTH_PATH:
            self.app = self._busy
        try:
            super().on_headers_complete()
        finally:
            self.app = app
        if not self.admitted:
            self.cycle.keep_alive = False  # a place of the reserve serves one request
        self._arm(limits.body_timeout_s, self._body_late)

    def on_message_complete(self) -> None:
        self._disarm()
        super().on_message_complete()

    def on_response_complete(self) -> None:
        super().on_response_complete()
        if self.timeout_keep_alive_task is not None:  # waiting for the next request
            self._wait()

    def _wait(self) -> None:
        self.idle_since = self.loop.time()
        self.waiting = next(_WAITING)

    def _path(self) -> bytes:
        try:
            path: bytes = httptools.parse_url(self.url).path
        except httptools.HttpParserInvalidURLError:
            return b""
        return path

    def _make_room(self) -> bool:
        """Close the connection idle longest to make room for this one; False if none has
        been idle for ``GIVES_WAY_AFTER_S``."""
        since = self.loop.time() - GIVES_WAY_AFTER_S
        idle = [
            other
            for other in self.connections
            if isinstance(other, BoundedHttpToolsProtocol)
            and other.idle_since is not None
            and other.idle_since <= since
            and not other.transport.is_closing()
        ]
        if not idle:
            return False
        oldest = min(idle, key=lambda other: other.waiting)
        oldest._end(oldest.began and oldest._answered(), "another client needed its connection")
        return True

    def _head_late(self) -> None:
        self._deadline = None
        seconds = self.limits.header_timeout_s
        detail = f"the request head did not arrive within {seconds:g} s"
        self._end(self.began and self._answered(), detail)

    def _body_late(self) -> None:
        self._deadline = None
        cycle = self.cycle
        say = not cycle.response_started
        cycle.disconnected = True  # the app waiting for the rest of the body is told it left
        cycle.message_event.set()
        seconds = self.limits.body_timeout_s
        self._end(say, f"the request body did not arrive within {seconds:g} s of its head")

    def _answered(self) -> bool:
        """Whether every request on the connection has been answered (a 408 may be said)."""
        return self.cycle is None or self.cycle.response_complete

    def _end(self, say: bool, detail: str) -> None:
        """Close the connection, first with a 408 saying why if ``say``."""
        self._disarm()
        if say:
            problem = Problem(
                type=PROBLEM_BASE + "request-timeout",
                title="Request timeout",
                status=408,
                detail=detail,
            )
            body = problem.model_dump_json(exclude_none=True).encode()
            head = [STATUS_LINE[408]]
            for name, value in self.server_state.default_headers:
                head += [name, b": ", value, b"\r\n"]
            head += [
                b"content-type: " + PROBLEM_JSON.encode() + b"\r\n",
                b"content-length: " + str(len(body)).encode() + b"\r\n",
                b"connection: close\r\n\r\n",
                body,
            ]
            self.transport.write(b"".join(head))
        self.transport.close()

    async def _busy(
        self, scope: Scope, receive: ASGIReceiveCallable, send: ASGISendCallable
    ) -> None:
        """The answer past ``max_connections``, but for /healthz."""
        problem = Problem(
            type=PROBLEM_BASE + "too-many-connections",
            title="Too many connections",
            status=503,
            detail=f"this API process serves {self.limits.max_connections} connections at once "
            "(NANONAV_API_MAX_CONNECTIONS) and has them all; try again shortly",
            instance=cast(str | None, scope.get("path")),
        )
        headers = {"Retry-After": str(BUSY_RETRY_AFTER_S), "Connection": "close"}
        respond = cast(ASGIApp, problem_response(problem, headers))
        await respond(cast(Any, scope), cast(Any, receive), cast(Any, send))

    def _arm(self, seconds: float, late: Any) -> None:
        self._disarm()
        self._deadline = self.loop.call_later(seconds, late)

    def _disarm(self) -> None:
        if self._deadline is not None:
            self._deadline.cancel()
            self._deadline = None
