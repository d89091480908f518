"""``make run``: migrate the database, start the API and one worker, stop both on Ctrl-C; a
worker that dies is started again, saying how it died.

The database is ``DATABASE_URL`` (default ``./var/nanonav.db``); the API listens on
``$HOST:$PORT`` (default 127.0.0.1:8000). The two parts run as child processes in their own
process groups, so a Ctrl-C reaches this supervisor only, which then stops them in order.
"""

from __future__ import annotations

import signal
import socket
import subprocess
import sys
import threading
import time
import urllib.error
import urllib.request
from pathlib import Path
from types import FrameType

from pydantic import ValidationError
from sqlalchemy.engine import make_url
from sqlalchemy.exc import SQLAlchemyError

from nanonav.cli.common import validation_messages
from nanonav.settings import Settings
from nanonav.store import JobStore
from nanonav.store.migrate import upgrade
from nanonav.store.queue import PRESENCE_WINDOW_S

READY_TIMEOUT_S = 60.0
STOP_TIMEOUT_S = 20.0


def _wait_until_ready(url: str, api: subprocess.Popen[bytes], stop: threading.Event) -> bool:
    deadline = time.monotonic() + READY_TIMEOUT_S
    while time.monotonic() < deadline and not stop.is_set() and api.poll() is None:
        try:
            with urllib.request.urlopen(f"{url}/healthz", timeout=2) as response:
                if response.status == 200:
                    return True
        except (urllib.error.URLError, OSError):
            pass
        stop.wait(0.2)
    return False


def next_free_port(host: str, port: int, *, tries: int = 100) -> int | None:
    """The first port after ``port`` that nothing listens on (within ``tries``), to suggest."""
    for candidate in range(port + 1, min(port + 1 + tries, 65536)):
        if not port_in_use(host, candidate):
            return candidate
    return None


def port_in_use(host: str, port: int) -> bool:
    """Whether something already listens on ``host:port``: then the API could not bind it, and
    the one answering /healthz there would be another server, taken for this one."""
    family = socket.AF_INET6 if ":" in host else socket.AF_INET
    with socket.socket(family, socket.SOCK_STREAM) as probe:
        probe.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            probe.bind((host, port))
        except OSError:
            return True
    return False


def _workers_seen(store: JobStore) -> int:
    """How many workers were seen lately, read from the database (0 if it cannot say): asking
    the API's /healthz twice a second would fill its access log while a worker compiles."""
    try:
        return store.census(seen_within_s=PRESENCE_WINDOW_S).workers
    except SQLAlchemyError:
        return 0


def _stop(children: list[subprocess.Popen[bytes]]) -> None:
    for child in children:
        if child.poll() is None:
            child.send_signal(signal.SIGTERM)
    for child in children:
        try:
            child.wait(timeout=STOP_TIMEOUT_S)
        except subprocess.TimeoutExpired:
            child.kill()
            child.wait()


def main() -> int:
    try:
        settings = Settings()
    except ValidationError as error:
        for line in validation_messages(error):
            print(f"nanonav: {line}", file=sys.stderr)
        return 2
    if port_in_use(settings.host, settings.port):
        free = next_free_port(settings.host, settings.port)
        choose = "choose another port" if free is None else f"`make run PORT={free}`, free now"
        print(
            f"nanonav: {settings.host}:{settings.port} is in use (another `make run`, or another "
            f"program): stop it, or {choose}",
            file=sys.stderr,
        )
        return 1
    shown = make_url(settings.database_url).render_as_string(hide_password=True)
    print(f"nanonav: migrating {shown}", flush=True)
    upgrade(settings.database_url)

    stop = threading.Event()

    def on_signal(signum: int, frame: FrameType | None) -> None:
        stop.set()

    signal.signal(signal.SIGINT, on_signal)
    signal.signal(signal.SIGTERM, on_signal)

    # `nanonav api`, so that the API is served as it is everywhere else (service/server.py)
    api = subprocess.Popen(
        [sys.executable, "-m", "nanonav.cli", "api", "--host", settings.host,
         "--port", str(settings.port)],
        start_new_session=True,
    )  # fmt: skip
    worker = _start_worker()
    children = [api, worker]
    url = f"http://{settings.host}:{settings.port}"
    store = JobStore.from_url(settings.database_url, busy_timeout_s=settings.store_busy_timeout_s)
    try:
        if _wait_until_ready(url, api, stop):
            command = Path(sys.executable).with_name("nanonav")
            print(
                f"nanonav: the API is at {url} (OpenAPI page: {url}/docs); Ctrl-C stops it\n"
                f"nanonav: the command line is {command} (or `source "
                f"{command.parent}/activate`, then `nanonav --help`)",
                flush=True,
            )
        # a starting worker compiles the engine first: say when jobs will run
        worker_ready = False
        while not stop.is_set():
            if not worker_ready and _workers_seen(store):
                worker_ready = True
                print("nanonav: a worker is ready; submitted jobs run now", flush=True)
            if api.poll() is not None:
                print("nanonav: the API stopped unexpectedly; stopping", file=sys.stderr)
                _stop(children)
                return 1
            if worker.poll() is not None and not stop.is_set():
                # a dead worker is not a dead service: its job goes back to the queue once its
                # lease runs out, and another worker takes it
                print(f"nanonav: the worker {_ended(worker.returncode)}; starting another",
                      file=sys.stderr, flush=True)  # fmt: skip
                worker = _start_worker()
                children[1] = worker
            stop.wait(0.5)
    finally:
        print("nanonav: stopping the API and the worker", flush=True)
        store.close()
        _stop(children)
    print("nanonav: stopped", flush=True)
    return 0


def _start_worker() -> subprocess.Popen[bytes]:
    return subprocess.Popen([sys.executable, "-m", "worker"], start_new_session=True)


def _ended(code: int) -> str:
    """How a process ended, in words: ``was killed by SIGKILL (out of memory?)``, ``exited
    with status 1``."""
    if code < 0:
        try:
            name = signal.Signals(-code).name
        except ValueError:
            name = f"signal {-code}"
        hint = " (out of memory?)" if -code == signal.SIGKILL else ""
        return f"was killed by {name}{hint}"
    return f"exited with status {code}"


if __name__ == "__main__":
    sys.exit(main())
