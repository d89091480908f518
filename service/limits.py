"""The request body limit: refused from Content-Length before reading, or while streaming."""

from __future__ import annotations

from starlette.datastructures import Headers
from starlette.types import ASGIApp, Message, Receive, Scope, Send

from service.numerals import positive_int
from service.problems import PROBLEM_BASE, BodyTooLarge, Problem, problem_response


class BodySizeLimit:
    """Pure ASGI middleware: bodies over ``max_bytes`` get 413, however they are sent."""

    def __init__(self, app: ASGIApp, max_bytes: int) -> None:
        self.app = app
        self.max_bytes = max_bytes

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        declared = Headers(scope=scope).get("content-length")
        status = None if declared is None else self._refusal(declared)
        if status is not None:
            problem = Problem(
                type=PROBLEM_BASE + ("body-too-large" if status == 413 else "bad-request"),
                title="Content too large" if status == 413 else "Bad request",
                status=status,
                detail=f"the request body is larger than {self.max_bytes} bytes"
                if status == 413
                else "the Content-Length header is not a number",
                instance=scope.get("path"),
            )
            await problem_response(problem, {"Connection": "close"})(scope, receive, send)
            return
        received = 0

        async def limited() -> Message:
            nonlocal received
            message = await receive()
            if message["type"] == "http.request":
                received += len(message.get("body", b""))
                if received > self.max_bytes:
                    raise BodyTooLarge(self.max_bytes)
            return message

        await self.app(scope, limited, send)

    def _refusal(self, declared: str) -> int | None:
        """400 for a Content-Length that is not ASCII digits, 413 for one over the limit; the
        leading zeros HTTP allows count for nothing (``int`` refuses over 4300 digits)."""
        if not (declared.isascii() and declared.isdigit()):
            return 400
        digits = declared.lstrip("0")
        if digits and positive_int(digits, maximum=self.max_bytes) is None:
            return 413
        return None
