"""HTTP caching in one place: strong ETags on GET answers, and 304 when the client has the answer.

A route says how long its answer may be kept: :data:`IMMUTABLE` for what never changes (the
results and pictures of a finished job or study). An answer that says nothing gets
``Cache-Control: no-cache``: a client may keep it but must ask again, and asking again with
``If-None-Match`` costs a 304 with no body while the answer is the same. The ETag is a digest of
the body as sent, so it changes exactly when the answer does, whatever changed it.

Only 200 answers whose body is sent in one piece are tagged: streamed ones (event streams, CSV
trajectories) pass through untouched. The digest is of the bytes this app sends; a compressing
middleware, if one is ever added, must sit inside this one or tag its own answers.
"""

from __future__ import annotations

import hashlib
import re

from starlette.concurrency import run_in_threadpool
from starlette.datastructures import Headers, MutableHeaders
from starlette.types import ASGIApp, Message, Receive, Scope, Send

# What a finished job's or study's results say: they never change again.
IMMUTABLE = {"Cache-Control": "max-age=86400, immutable"}
REVALIDATE = "no-cache"
# Hashing a large body (a trajectory can be tens of MB) happens off the event loop.
THREAD_ABOVE_BYTES = 1 << 20
# An entity tag in an If-None-Match list, weak or not (RFC 9110 section 8.8.3).
_TAG = re.compile(r'(?:W/)?("[^"]*")')
# Headers a 304 keeps (RFC 9110 section 15.4.5); the body's own headers go.
_DROPPED_ON_304 = ("content-type", "content-length", "content-encoding", "content-disposition")


def etag(body: bytes) -> str:
    """A strong entity tag for ``body``."""
    return '"' + hashlib.blake2b(body, digest_size=16).hexdigest() + '"'


def none_match(if_none_match: str, tag: str) -> bool:
    """Whether an If-None-Match header matches ``tag``: ``*`` matches any current answer, and
    tags compare weakly (``W/"x"`` matches ``"x"``), as RFC 9110 section 13.1.2 says."""
    if if_none_match.strip() == "*":
        return True
    opaque = tag.removeprefix("W/")
    return any(found.group(1) == opaque for found in _TAG.finditer(if_none_match))


class ETags:
    """Pure ASGI middleware: tags GET and HEAD answers and answers 304 on a match."""

    def __init__(self, app: ASGIApp) -> None:
        self.app = app

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http" or scope["method"] not in ("GET", "HEAD"):
            await self.app(scope, receive, send)
            return
        if_none_match = Headers(scope=scope).get("if-none-match")
        held: Message | None = None

        async def tagging(message: Message) -> None:
            nonlocal held
            if message["type"] == "http.response.start" and _taggable(message):
                held = message  # sent once the body shows whether it comes in one piece
                return
            if message["type"] != "http.response.body" or held is None:
                await send(message)
                return
            start, held = held, None
            if message.get("more_body", False):
                await send(start)
                await send(message)
                return
            await _send_tagged(send, start, message, if_none_match)

        await self.app(scope, receive, tagging)


def _taggable(start: Message) -> bool:
    content_type = Headers(raw=start["headers"]).get("content-type", "")
    return bool(start["status"] == 200 and not content_type.startswith("text/event-stream"))


async def _send_tagged(
    send: Send, start: Message, body: Message, if_none_match: str | None
) -> None:
    headers = MutableHeaders(scope=start)
    content: bytes = body.get("body", b"")
    tag = headers.get("etag")
    if tag is None:
        if len(content) > THREAD_ABOVE_BYTES:
            tag = await run_in_threadpool(etag, content)
        else:
            tag = etag(content)
        headers["ETag"] = tag
    if "cache-control" not in headers:
        headers["Cache-Control"] = REVALIDATE
    if if_none_match is None or not none_match(if_none_match, tag):
        await send(start)
        await send(body)
        return
    for name in _DROPPED_ON_304:
        del headers[name]
    await send({**start, "status": 304})
    await send({"type": "http.response.body", "body": b""})
