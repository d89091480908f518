"""The request body limit as Content-Length declares it: a number of ASCII digits or a 400."""

from __future__ import annotations

import asyncio
import contextlib
import json
from typing import Any

import pytest
from starlette.types import Message, Receive, Scope, Send

from service.limits import BodySizeLimit
from tests.conftest import Api
from tests.raw_http import connect, read_answer

LIMIT = 1000


async def _reached(scope: Scope, receive: Receive, send: Send) -> None:
    await send({"type": "http.response.start", "status": 204, "headers": []})
    await send({"type": "http.response.body", "body": b""})


def answer_to(length: bytes) -> tuple[int, dict[str, Any] | None]:
    """The status the limit answers a POST declaring ``length`` with, and its problem if any."""
    scope = {"type": "http", "method": "POST", "path": "/jobs",
             "headers": [(b"content-length", length)]}  # fmt: skip
    sent: list[Message] = []

    async def receive() -> Message:
        return {"type": "http.request", "body": b"", "more_body": False}

    async def send(message: Message) -> None:
        sent.append(message)

    asyncio.run(BodySizeLimit(_reached, max_bytes=LIMIT)(scope, receive, send))
    body = b"".join(m.get("body", b"") for m in sent if m["type"] == "http.response.body")
    return sent[0]["status"], json.loads(body) if body else None


@pytest.mark.parametrize(
    "length",
    [
        b"\xb2", b"\xb9",  # superscripts in latin-1: str.isdigit takes them, int refuses them
        "\u0661".encode(),  # Arabic-Indic one (as UTF-8 bytes)
        b"-1", b"+1", b" 1", b"1.0", b"", b"0x10",
    ],
)  # fmt: skip
def test_a_content_length_that_is_not_ascii_digits_is_400(length: bytes) -> None:
    status, problem = answer_to(length)
    assert status == 400 and problem is not None
    assert problem["detail"] == "the Content-Length header is not a number"


@pytest.mark.parametrize("length", [b"0", b"1", b"0001", b"1000", b"0" * 5000 + b"1000"])
def test_a_content_length_within_the_limit_passes_leading_zeros_and_all(length: bytes) -> None:
    assert answer_to(length) == (204, None)


@pytest.mark.parametrize("length", [b"1001", b"0" * 5000 + b"1001", b"9" * 5000])
def test_a_content_length_over_the_limit_is_413_however_long_it_is(length: bytes) -> None:
    status, problem = answer_to(length)
    assert status == 413 and problem is not None and problem["type"].endswith("body-too-large")


def test_thousands_of_leading_zeros_in_content_length_are_read_as_http_allows(api: Api) -> None:
    # int() refuses over 4300 digits: the limit said 500 to a header the server had accepted
    with contextlib.closing(connect(api.url)) as sock:
        sock.sendall(b"POST /jobs HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Type: application/json\r\n"
                     b"Content-Length: " + b"0" * 4400 + b"2\r\n\r\n{}")  # fmt: skip
        assert read_answer(sock).status == 202
