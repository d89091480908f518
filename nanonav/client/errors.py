"""How a call of the client fails: the server's problem document, or no answer at all."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import httpx

from nanonav.status import Status as Status  # a public name of the client too


class ApiError(Exception):
    """A call that failed: the server's problem document (RFC 9457), field by field.

    ``errors`` lists the offending inputs as the server names them: each a dict with
    ``pointer`` (into the JSON body, ``#/robots/count``) or ``parameter`` (a query or path
    parameter), and ``detail``."""

    def __init__(
        self,
        status: int,
        title: str,
        detail: str | None = None,
        *,
        type: str = "about:blank",
        errors: Sequence[Mapping[str, Any]] = (),
        instance: str | None = None,
    ) -> None:
        self.status = status
        self.title = title
        self.detail = detail
        self.type = type
        self.errors = [dict(e) for e in errors]
        self.instance = instance
        super().__init__(self._message())

    @classmethod
    def of(cls, response: httpx.Response) -> ApiError:
        """The error a non-2xx answer stands for, problem document or not."""
        try:
            body = response.json()
        except ValueError:
            body = None
        if not isinstance(body, dict) or "title" not in body:
            text = response.text.strip()[:200]
            return cls(
                response.status_code,
                response.reason_phrase or "Error",
                text or None,
                instance=response.request.url.path,
            )
        errors = body.get("errors")
        return cls(
            int(body.get("status", response.status_code)),
            str(body["title"]),
            body.get("detail"),
            type=str(body.get("type", "about:blank")),
            errors=[e for e in errors if isinstance(e, dict)] if isinstance(errors, list) else (),
            instance=body.get("instance"),
        )

    @property
    def field_messages(self) -> list[str]:
        """One ``where: what`` line per offending input."""
        lines = []
        for error in self.errors:
            loc = error.get("loc")
            where = (
                error.get("pointer")
                or error.get("parameter")
                or ("/".join(map(str, loc)) if isinstance(loc, list) else "")
            )
            lines.append(
                f"{where}: {error.get('detail', '')}" if where else error.get("detail", "")
            )
        return lines

    def _message(self) -> str:
        head = f"{self.status} {self.title}" + (f": {self.detail}" if self.detail else "")
        fields = self.field_messages
        if fields == [self.detail]:  # the detail already is the only field's message
            return head
        return "\n".join([head, *(f"  {line}" for line in fields)])


class ServerUnreachable(ApiError):
    """No answer came: nothing listens at the URL, it timed out, or the connection broke."""

    def __init__(self, url: str, reason: str) -> None:
        self.url = url
        super().__init__(
            0,
            "Server unreachable",
            f"cannot reach the NanoNav API at {url}: {reason}",
            type="urn:nanonav:client:unreachable",
        )

    def _message(self) -> str:
        return self.detail or self.title
