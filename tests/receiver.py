"""A real HTTP(S) server on a free local port that records the webhooks it gets, for tests."""

from __future__ import annotations

import ssl
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer


@dataclass(frozen=True)
class Received:
    path: str
    headers: dict[str, str]
    body: bytes
    local_address: str = ""  # the address of this machine the request came in on


@dataclass
class Receiver:
    """What it got, and the statuses it answers with, in turn (the last one from then on)."""

    url: str
    port: int = 0
    statuses: list[int] = field(default_factory=lambda: [200])
    delay_s: float = 0.0  # how long it takes to answer
    got: list[Received] = field(default_factory=list)
    server_names: list[str | None] = field(default_factory=list)  # TLS SNI, per handshake
    _lock: threading.Lock = field(default_factory=threading.Lock)

    def answer(self, request: Received) -> int:
        with self._lock:
            self.got.append(request)
            return self.statuses[min(len(self.got), len(self.statuses)) - 1]

    def wait_for(self, count: int, timeout_s: float = 20.0) -> list[Received]:
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            with self._lock:
                if len(self.got) >= count:
                    return list(self.got)
            time.sleep(0.02)
        raise AssertionError(f"the receiver got {len(self.got)} webhook(s), not {count}")


@contextmanager
def receiving(
    statuses: list[int] | None = None,
    delay_s: float = 0.0,
    *,
    bind: str = "127.0.0.1",
    name: str = "localhost",
    tls: ssl.SSLContext | None = None,
) -> Iterator[Receiver]:
    """A receiver listening on ``bind``, at ``http://<name>:<port>/hook`` (``https://`` with
    ``tls``, a server context whose handshakes it records), until the block ends."""
    receiver: Receiver

    class Handler(BaseHTTPRequestHandler):
        def do_POST(self) -> None:
            body = self.rfile.read(int(self.headers.get("Content-Length", "0")))
            headers = {k.lower(): v for k, v in self.headers.items()}
            local = str(self.connection.getsockname()[0])
            status = receiver.answer(Received(self.path, headers, body, local))
            time.sleep(receiver.delay_s)
            self.send_response(status)
            self.send_header("Content-Length", "0")
            self.end_headers()

        def log_message(self, format: str, *args: object) -> None:
            pass

    server = ThreadingHTTPServer((bind, 0), Handler)
    server.daemon_threads = True
    port = server.server_address[1]
    scheme = "http"
    if tls is not None:

        def seen(sock: ssl.SSLObject, server_name: str | None, context: ssl.SSLContext) -> None:
            receiver.server_names.append(server_name)

        tls.sni_callback = seen
        server.socket = tls.wrap_socket(server.socket, server_side=True)
        scheme = "https"
    receiver = Receiver(url=f"{scheme}://{name}:{port}/hook", port=port, delay_s=delay_s)
    if statuses:
        receiver.statuses = statuses
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    try:
        yield receiver
    finally:
        server.shutdown()
        server.server_close()
