"""HTTP/1.1 over a bare socket, for the tests whose client misbehaves: half a request head, a
body sent a byte at a time, a connection held open without a word."""

from __future__ import annotations

import contextlib
import json
import socket
import time
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from typing import Any
from urllib.parse import urlsplit


@dataclass
class Answer:
    """A response as it arrived: status, headers (names in lower case) and body."""

    status: int
    headers: dict[str, str]
    body: bytes

    def json(self) -> Any:
        return json.loads(self.body)


def connect(url: str, source: str | None = None) -> socket.socket:
    """A connection to the server at ``url``, from the loopback address ``source`` if given."""
    parts = urlsplit(url)
    sock = socket.create_connection(
        (parts.hostname or "127.0.0.1", parts.port or 80),
        timeout=5,
        source_address=(source, 0) if source else None,
    )
    sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
    return sock


@contextlib.contextmanager
def connections(url: str, count: int) -> Iterator[list[socket.socket]]:
    """``count`` open connections that have said nothing, closed afterwards."""
    opened = [connect(url) for _ in range(count)]
    try:
        yield opened
    finally:
        for sock in opened:
            sock.close()


def head(method: str, path: str, headers: dict[str, str] | None = None) -> bytes:
    """A request head, its blank line included."""
    lines = [f"{method} {path} HTTP/1.1", "Host: 127.0.0.1"]
    lines += [f"{name}: {value}" for name, value in (headers or {}).items()]
    return ("\r\n".join(lines) + "\r\n\r\n").encode()


def parse(received: bytes) -> Answer:
    """The first response in ``received``; its body up to Content-Length, else all the rest."""
    top, separator, rest = received.partition(b"\r\n\r\n")
    assert separator, f"no complete response head in {received!r}"
    status_line, *header_lines = top.decode("latin-1").split("\r\n")
    headers = {}
    for line in header_lines:
        name, _, value = line.partition(":")
        headers[name.strip().lower()] = value.strip()
    length = headers.get("content-length")
    body = rest[: int(length)] if length is not None else rest
    return Answer(int(status_line.split()[1]), headers, body)


def read_head(sock: socket.socket, timeout_s: float = 5.0) -> Answer:
    """Read until a response head has arrived (a stream's head comes before its events)."""
    sock.settimeout(timeout_s)
    received = b""
    while b"\r\n\r\n" not in received:
        data = sock.recv(65536)
        assert data, f"the server closed the connection after {received!r}"
        received += data
    return parse(received)


def read_answer(sock: socket.socket, timeout_s: float = 5.0) -> Answer:
    """Read one whole response with a Content-Length."""
    sock.settimeout(timeout_s)
    received = b""
    while True:
        if b"\r\n\r\n" in received:
            answer = parse(received)
            if len(answer.body) >= int(answer.headers.get("content-length", "0")):
                return answer
        data = sock.recv(65536)
        assert data, f"the server closed the connection after {received!r}"
        received += data


def read_answer_rest(sock: socket.socket, answer: Answer, timeout_s: float = 5.0) -> Answer:
    """``answer`` (from :func:`read_head`) with the rest of its Content-Length body read."""
    sock.settimeout(timeout_s)
    body = answer.body
    while len(body) < int(answer.headers.get("content-length", "0")):
        data = sock.recv(65536)
        assert data, f"the server closed the connection after {body!r}"
        body += data
    return Answer(answer.status, answer.headers, body)


def ask(url: str, method: str, path: str, headers: dict[str, str] | None = None) -> Answer:
    """One request on a fresh connection, closed afterwards."""
    with contextlib.closing(connect(url)) as sock:
        sock.sendall(head(method, path, headers))
        return read_answer(sock)


@dataclass
class Closed:
    """How a connection ended: after how long (None: still open at the deadline), and all the
    server sent on it."""

    after_s: float | None
    received: bytes


def trickle(sock: socket.socket, pieces: Sequence[bytes], every_s: float, limit_s: float) -> Closed:
    """Send ``pieces`` one every ``every_s`` (then nothing) while reading what comes back, until
    the server closes the connection or ``limit_s`` has passed."""
    started = time.monotonic()
    received = b""
    queue = list(pieces)
    next_send = started
    while (now := time.monotonic()) - started < limit_s:
        if queue and now >= next_send:
            with contextlib.suppress(OSError):  # the server may have closed it meanwhile
                sock.sendall(queue.pop(0))
            next_send = now + every_s
        wait = max(min(next_send - now if queue else limit_s, started + limit_s - now), 0.01)
        sock.settimeout(wait)
        try:
            data = sock.recv(65536)
        except TimeoutError:
            continue
        except ConnectionError:
            return Closed(time.monotonic() - started, received)
        if not data:
            return Closed(time.monotonic() - started, received)
        received += data
    return Closed(None, received)


def is_closed(sock: socket.socket, within_s: float) -> bool:
    """Whether the server closes ``sock`` (which it has answered nothing on) within ``within_s``."""
    return trickle(sock, [], within_s, within_s).after_s is not None
