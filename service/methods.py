"""HTTP methods as RFC 9110 has them: every GET route answers HEAD, and a 405 says in ``Allow``
every method its path takes, not only those of the first route that matched it."""

from __future__ import annotations

from collections.abc import Iterable

from starlette.routing import BaseRoute, Match, Mount
from starlette.staticfiles import StaticFiles
from starlette.types import ASGIApp, Message, Receive, Scope, Send

# The order methods are listed in, for an Allow header that reads the same every time.
ORDER = ("GET", "HEAD", "POST", "PUT", "PATCH", "DELETE", "OPTIONS")


def allowed_methods(routes: Iterable[BaseRoute], scope: Scope) -> list[str]:
    """Every method some route takes at the path of ``scope`` (a request's, as routed); HEAD
    wherever GET is."""
    found: set[str] = set()
    for route in routes:
        if isinstance(route, Mount):
            if isinstance(route.app, StaticFiles) and route.matches(scope)[0] is not Match.NONE:
                found |= {"GET", "HEAD"}
            continue
        found |= {m for m in ORDER if route.matches({**scope, "method": m})[0] is Match.FULL}
    if "GET" in found:
        found.add("HEAD")
    return sorted(found, key=ORDER.index)


class HeadAsGet:
    """Pure ASGI middleware: a HEAD request runs as the GET it stands for and gets that answer's
    status and headers with no body. Once the headers are sent the app is told the client left,
    so a streamed answer (an event stream, a CSV) stops rather than being produced for no one."""

    def __init__(self, app: ASGIApp) -> None:
        self.app = app

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http" or scope["method"] != "HEAD":
            await self.app(scope, receive, send)
            return
        answered = False

        async def headers_only(message: Message) -> None:
            nonlocal answered
            if answered:
                return
            if message["type"] == "http.response.body":
                answered = True
                await send({"type": "http.response.body", "body": b"", "more_body": False})
                return
            await send(message)

        async def leave_once_answered() -> Message:
            if answered:
                return {"type": "http.disconnect"}
            return await receive()

        await self.app({**scope, "method": "GET"}, leave_once_answered, headers_only)
