"""Slow clients and many event streams against one real API process (``nanonav api``), on loopback.

From this one asyncio process, over raw sockets, it opens one kind of client at a time:

- ``headers``: ``--slow-headers`` connections (1000) that send a request line, then a header
  line every 5 s, and never the blank line that ends the head;
- ``bodies``: ``--trickles`` POSTs (300) whose head declares a 10,000-byte body, sent a byte a
  second;
- ``streams``: ``--streams`` event streams (2000) of a running job (this process writes its
  progress 4 times a second, as a worker would), from ``--addresses`` client addresses (40);
- ``flood``: ``--flood`` slow-header connections (2100) against an API process whose open-file
  limit is ``--open-files`` (2048), probing ``/healthz`` ``--probes`` times (30) meanwhile,
  0.3 s apart.

While the first three are open, ``wrk`` (``apt-get install wrk``) asks for ``GET /jobs/{id}`` and
``/healthz`` for ``--wrk-s`` seconds each (4); each part prints wrk's p50/p95/p99, its errors and
non-2xx answers, and how many of its connections are still open ``--hold-s`` seconds after they
were opened (15; ``bodies`` waits ``--body-hold-s``, 35). ``baseline`` measures the same with no
slow client. Extra settings for the API (``--api-env NANONAV_API_HEADER_TIMEOUT_S=1``) are
passed in its environment.

    .venv/bin/python benchmarks/slow_clients.py [--parts baseline,headers,bodies,streams,flood]
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import os
import resource
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

import httpx

from nanonav.store import JobStore
from nanonav.store.migrate import upgrade

PARTS = ("baseline", "headers", "bodies", "streams", "flood")
HOST = "127.0.0.1"
WRK_SCRIPT = """
done = function(summary, latency, requests)
  local e = summary.errors
  io.write(string.format("RESULT %d %d %d %d %d %d %.2f %.2f %.2f\\n", summary.requests,
    e.connect, e.read, e.write, e.status, e.timeout, latency:percentile(50) / 1000,
    latency:percentile(95) / 1000, latency:percentile(99) / 1000))
end
"""


def free_port() -> int:
    import socket

    with socket.socket() as sock:
        sock.bind((HOST, 0))
        port: int = sock.getsockname()[1]
        return port


@dataclass
class Api:
    url: str
    database_url: str
    process: subprocess.Popen[bytes]


@contextlib.contextmanager
def api(workdir: Path, env: dict[str, str], open_files: int | None = None) -> Iterator[Api]:
    """``nanonav api`` on a fresh SQLite file, with ``open_files`` as its open-file limit."""
    database_url = f"sqlite:///{workdir / f'nanonav-{time.monotonic_ns()}.db'}"
    upgrade(database_url)
    port = free_port()
    environment = {
        **{k: v for k, v in os.environ.items() if not k.startswith("NANONAV_")},
        **env,
        "NANONAV_DATABASE_URL": database_url,
    }
    environment.pop("DATABASE_URL", None)

    def limit() -> None:
        if open_files is not None:
            resource.setrlimit(resource.RLIMIT_NOFILE, (open_files, open_files))

    command = [sys.executable, "-m", "nanonav.cli", "api", "--host", HOST, "--port", str(port)]
    with (workdir / "api.log").open("ab") as log:
        process = subprocess.Popen(command, env=environment, stdout=log,
                                   stderr=subprocess.STDOUT, preexec_fn=limit)  # fmt: skip
    url = f"http://{HOST}:{port}"
    try:
        deadline = time.monotonic() + 90
        while True:
            if process.poll() is not None or time.monotonic() > deadline:
                raise RuntimeError(f"the API did not start; see {workdir / 'api.log'}")
            with contextlib.suppress(httpx.TransportError):
                if httpx.get(f"{url}/healthz", timeout=2).status_code == 200:
                    break
            time.sleep(0.1)
        yield Api(url, database_url, process)
    finally:
        process.send_signal(signal.SIGTERM)
        try:
            process.wait(timeout=30)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait()


@dataclass
class Wrk:
    requests: int
    errors: int  # connect, read, write and timeout errors
    non_2xx: int
    p50_ms: float
    p95_ms: float
    p99_ms: float

    def __str__(self) -> str:
        return (
            f"p50 {self.p50_ms:7.1f}  p95 {self.p95_ms:7.1f}  p99 {self.p99_ms:7.1f} ms  "
            f"{self.requests:6d} answers  {self.non_2xx:5d} non-2xx  {self.errors:5d} errors"
        )


async def wrk(url: str, seconds: float, script: Path) -> Wrk:
    """wrk with 4 connections on one thread for ``seconds``, its figures from ``script``."""
    command = ["wrk", "-t1", "-c4", f"-d{seconds:g}s", "--timeout", "5s", "-s", str(script), url]
    child = await asyncio.create_subprocess_exec(*command, stdout=asyncio.subprocess.PIPE,
                                                 stderr=asyncio.subprocess.STDOUT)  # fmt: skip
    out, _ = await child.communicate()
    line = next((x for x in out.decode().splitlines() if x.startswith("RESULT ")), None)
    if line is None:
        return Wrk(0, 0, 0, float("nan"), float("nan"), float("nan"))
    n, connect, read, write, status, timeout, p50, p95, p99 = line.split()[1:]
    errors = int(connect) + int(read) + int(write) + int(timeout)
    return Wrk(int(n), errors, int(status), float(p50), float(p95), float(p99))


@dataclass
class Slow:
    """One misbehaving connection: when it was closed (None: open), what it was answered."""

    closed_at: float | None = None
    answer: bytes = b""

    @property
    def status(self) -> str:
        return self.answer[9:12].decode("latin-1") if self.answer.startswith(b"HTTP/") else ""


async def hold(
    port: int, first: bytes, then: bytes, every_s: float, source: str | None = None
) -> Slow:
    """Send ``first``, then ``then`` every ``every_s``, reading all that comes, until closed."""
    slow = Slow()
    try:
        local = (source, 0) if source else None
        reader, writer = await asyncio.open_connection(HOST, port, local_addr=local)
    except OSError:
        slow.closed_at = time.monotonic()
        return slow
    try:
        writer.write(first)
        while True:
            try:
                data = await asyncio.wait_for(reader.read(65536), every_s)
            except TimeoutError:
                if then:
                    writer.write(then)
                continue
            if not data:
                break
            if len(slow.answer) < 64:
                slow.answer += data[:64]
    except (OSError, asyncio.CancelledError):
        pass
    finally:
        slow.closed_at = slow.closed_at or time.monotonic()
        writer.close()
    return slow


async def open_many(
    make: Callable[[int], asyncio.Task[Slow]], count: int
) -> list[asyncio.Task[Slow]]:
    """``count`` connections, opened 100 at a time (the listen backlog drops a burst)."""
    tasks = []
    for i in range(count):
        tasks.append(make(i))
        if i % 100 == 99:
            await asyncio.sleep(0.05)
    return tasks


async def measure(service: Api, job_id: int, seconds: float, script: Path) -> tuple[Wrk, Wrk]:
    job = await wrk(f"{service.url}/jobs/{job_id}", seconds, script)
    health = await wrk(f"{service.url}/healthz", seconds, script)
    return job, health


def report(part: str, what: str, figures: tuple[Wrk, Wrk] | None, extra: str) -> None:
    print(f"{part}: {what}")
    if figures is not None:
        print(f"  GET /jobs/{{id}}  {figures[0]}")
        print(f"  GET /healthz    {figures[1]}")
    print(f"  {extra}", flush=True)


async def wait_until(started: float, hold_s: float) -> None:
    await asyncio.sleep(max(started + hold_s - time.monotonic(), 0))


async def cancel(tasks: list[asyncio.Task[Slow]]) -> list[Slow]:
    for task in tasks:
        task.cancel()
    found = await asyncio.gather(*tasks, return_exceptions=True)
    return [slow for slow in found if isinstance(slow, Slow)]


async def slow_part(
    part: str, service: Api, job_id: int, args: argparse.Namespace, script: Path
) -> None:
    port = int(service.url.rsplit(":", 1)[1])
    if part == "headers":
        first, then = b"GET /healthz HTTP/1.1\r\nHost: 127.0.0.1\r\n", b"X-Slow: 1\r\n"
        every, count, hold_s = 5.0, args.slow_headers, args.hold_s
        what = f"{count} connections sending a header line every 5 s"
    else:
        first = (b"POST /jobs HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Type: application/json\r\n"
                 b"Content-Length: 10000\r\n\r\n{")  # fmt: skip
        then, every, count, hold_s = b" ", 1.0, args.trickles, args.body_hold_s
        what = f"{count} POSTs sending their 10,000-byte body a byte a second"
    started = time.monotonic()
    tasks = await open_many(lambda i: asyncio.create_task(hold(port, first, then, every)), count)
    await asyncio.sleep(1)
    figures = await measure(service, job_id, args.wrk_s, script)
    await wait_until(started, hold_s)
    left = sum(not task.done() for task in tasks)
    slows = await cancel(tasks)
    answers = sorted({s.status for s in slows if s.status})
    report(part, what, figures, f"{left} of {count} still open after {hold_s:g} s; "
           f"answers they got: {', '.join(answers) or 'none'}")  # fmt: skip


def drive_progress(
    database_url: str, job_id: int, claimed: threading.Event, stop: threading.Event
) -> None:
    """Run the job as a worker would, as far as its streams can tell: progress 4 times a s."""
    store = JobStore.from_url(database_url)
    claim = store.claim("benchmark", lease_s=600)
    claimed.set()
    assert claim is not None and claim.job.id == job_id
    step = 0
    while not stop.wait(0.25):
        step += 1
        store.report_progress(claim, episode=step % 1000, episodes=1000,
                              fraction=(step % 1000) / 1000, lease_s=600)  # fmt: skip
    store.close()


async def open_stream(port: int, path: str, source: str) -> tuple[str, asyncio.Task[Slow] | None]:
    """A stream's status, and for a 200 the task that keeps reading it."""
    reader, writer = await asyncio.open_connection(HOST, port, local_addr=(source, 0))
    try:
        writer.write(f"GET {path} HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n".encode())
        head = await asyncio.wait_for(reader.readuntil(b"\r\n\r\n"), 30)
    except BaseException:
        writer.close()  # else it is closed when collected, after its loop, with a warning
        raise
    status = head[9:12].decode()
    if status != "200":
        writer.close()
        return status, None

    async def drain() -> Slow:
        with contextlib.suppress(OSError, asyncio.CancelledError):
            while await reader.read(65536):
                pass
        writer.close()
        return Slow(closed_at=time.monotonic())

    return status, asyncio.create_task(drain())


async def streams_part(service: Api, job_id: int, args: argparse.Namespace, script: Path) -> None:
    port = int(service.url.rsplit(":", 1)[1])
    sources = [f"127.0.0.{2 + i}" for i in range(args.addresses)]
    claimed, stop = threading.Event(), threading.Event()
    driver = threading.Thread(
        target=drive_progress, args=(service.database_url, job_id, claimed, stop)
    )
    driver.start()
    # the driver's first connection and claim hold the interpreter in turns with this loop:
    # streams open once it runs, as a worker's progress would come from another process
    await asyncio.to_thread(claimed.wait, 30)
    statuses: dict[str, int] = {}
    tasks: list[asyncio.Task[Slow]] = []
    try:
        for start in range(0, args.streams, 100):
            opened = await asyncio.gather(
                *(open_stream(port, f"/jobs/{job_id}/events", sources[i % len(sources)])
                  for i in range(start, min(start + 100, args.streams))),
                return_exceptions=True,
            )  # fmt: skip
            for found in opened:
                status = found[0] if isinstance(found, tuple) else type(found).__name__
                statuses[status] = statuses.get(status, 0) + 1
                if isinstance(found, tuple) and found[1] is not None:
                    tasks.append(found[1])
        figures = await measure(service, job_id, args.wrk_s, script)
        left = sum(not task.done() for task in tasks)
    finally:
        stop.set()
        driver.join()
        await cancel(tasks)
    shown = ", ".join(f"{n} {status}" for status, n in sorted(statuses.items()))
    report("streams", f"{args.streams} event streams of a running job from {args.addresses} "
           "addresses", figures, f"answered: {shown}; {left} open while measured")  # fmt: skip


async def flood_part(service: Api, args: argparse.Namespace) -> None:
    port = int(service.url.rsplit(":", 1)[1])
    first, then = b"GET /healthz HTTP/1.1\r\nHost: 127.0.0.1\r\n", b"X-Slow: 1\r\n"
    started = time.monotonic()
    tasks = await open_many(lambda i: asyncio.create_task(hold(port, first, then, 5.0)),
                            args.flood)  # fmt: skip
    await asyncio.sleep(1)
    answered = 0
    waits: list[float] = []
    async with httpx.AsyncClient(timeout=2) as client:
        for _ in range(args.probes):
            asked = time.monotonic()
            with contextlib.suppress(httpx.HTTPError):
                if (await client.get(f"{service.url}/healthz")).status_code == 200:
                    answered += 1
                    waits.append(time.monotonic() - asked)
            await asyncio.sleep(max(asked + 0.3 - time.monotonic(), 0))
    await wait_until(started, args.hold_s)
    left = sum(not task.done() for task in tasks)
    await cancel(tasks)
    slowest = f", slowest {max(waits) * 1000:.0f} ms" if waits else ""
    report("flood", f"{args.flood} slow-header connections, open-file limit {args.open_files}",
           None, f"/healthz answered 200 {answered} of {args.probes} times{slowest}; {left} of "
           f"{args.flood} still open after {args.hold_s:g} s")  # fmt: skip


async def run_parts(args: argparse.Namespace, workdir: Path, env: dict[str, str]) -> None:
    script = workdir / "stats.lua"
    script.write_text(WRK_SCRIPT)
    parts = args.parts
    if any(part != "flood" for part in parts):
        with api(workdir, env) as service:
            response = httpx.post(f"{service.url}/jobs", json={})
            job_id = response.json()["id"]
            await measure(service, job_id, 1, script)  # warm up
            for part in parts:
                if part == "baseline":
                    figures = await measure(service, job_id, args.wrk_s, script)
                    report("baseline", "no slow client", figures, "-")
                elif part in ("headers", "bodies"):
                    await slow_part(part, service, job_id, args, script)
                elif part == "streams":
                    await streams_part(service, job_id, args, script)
                await asyncio.sleep(1)  # the server notices the connections closed
    if "flood" in parts:
        with api(workdir, env, open_files=args.open_files) as service:
            await flood_part(service, args)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--parts", default=",".join(PARTS),
                        help=f"comma-separated, of {', '.join(PARTS)} (all)")  # fmt: skip
    parser.add_argument("--slow-headers", type=int, default=1000)
    parser.add_argument("--trickles", type=int, default=300)
    parser.add_argument("--streams", type=int, default=2000)
    parser.add_argument("--addresses", type=int, default=40, help="stream client addresses")
    parser.add_argument("--flood", type=int, default=2100)
    parser.add_argument("--open-files", type=int, default=2048, help="the flooded API's limit")
    parser.add_argument("--probes", type=int, default=30, help="/healthz probes in the flood")
    parser.add_argument("--wrk-s", type=float, default=4.0, help="seconds of each wrk run")
    parser.add_argument("--hold-s", type=float, default=15.0)
    parser.add_argument("--body-hold-s", type=float, default=35.0)
    parser.add_argument("--api-env", action="append", default=[], metavar="NAME=VALUE")
    args = parser.parse_args(argv)
    args.parts = [part.strip() for part in args.parts.split(",") if part.strip()]
    if unknown := set(args.parts) - set(PARTS):
        parser.error(f"unknown parts: {', '.join(sorted(unknown))}")
    if shutil.which("wrk") is None:
        print("wrk is not installed: apt-get install wrk", file=sys.stderr)
        return 2
    env = dict(item.split("=", 1) for item in args.api_env)
    soft, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
    needed = max(args.slow_headers, args.trickles, args.streams, args.flood) + 256
    if soft < needed:
        resource.setrlimit(resource.RLIMIT_NOFILE, (min(needed, hard), hard))
    workdir = Path(tempfile.mkdtemp(prefix="nanonav-slow-clients-"))
    started = time.monotonic()
    asyncio.run(run_parts(args, workdir, env))
    print(f"({time.monotonic() - started:.0f} s; the API's log is {workdir / 'api.log'})")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
