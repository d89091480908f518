"""The API under load, on real processes: one uvicorn API and two workers on loopback.

``--clients`` concurrent clients (50) each submit a small job, poll ``GET /jobs/{id}`` every
``--pause`` seconds until it ends, and start again, for ``--duration`` seconds (60) or until
``--max-requests`` were sent. Prints requests per second, p50/p99/max per route and the number
of errors (any answer but 2xx, or no answer). SQLite in a temporary directory unless
``--database-url`` names another store (it is migrated first, and its jobs are left there).

The clients are Python too, on the same cores: ``--client-processes`` spreads them over several
processes, as separate programs would be, and ``--floor`` first runs the same clients against a
server that does nothing, to show what the clients and the machine alone cost.

    .venv/bin/python benchmarks/load.py [--duration 60] [--clients 50] [--pause 0.1]
                                        [--client-processes 1] [--floor]
                                        [--api-processes 1] [--database-url URL]
"""

from __future__ import annotations

import argparse
import asyncio
import itertools
import json
import multiprocessing
import os
import resource
import signal
import socket
import subprocess
import sys
import tempfile
import time
from collections import defaultdict
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from multiprocessing.synchronize import Barrier
from pathlib import Path
from typing import Any

import httpx

# A small job: tens of milliseconds of simulation, so the two workers are always busy.
SMALL: dict[str, Any] = {"robots": {"count": 2}, "learning": {"episodes": 3, "max_steps": 100},
                         "evaluation": {"worlds": 2}}  # fmt: skip
ENDED = {"succeeded", "failed", "cancelled"}
SUBMIT, POLL = "POST /jobs", "GET /jobs/{id}"


def free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        port: int = sock.getsockname()[1]
        return port


def percentile(values: list[float], q: float) -> float:
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, max(0, round(q / 100 * (len(ordered) - 1))))]


def cpu_seconds(roots: list[int]) -> float | None:
    """CPU time (user + system) so far of the processes ``roots`` and all they started, from
    ``/proc``; None where there is no ``/proc``."""
    tree: dict[int, list[int]] = defaultdict(list)
    used: dict[int, int] = {}
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            line = stat.read_text()
        except OSError:  # it ended meanwhile
            continue
        fields = line[line.rfind(")") + 2 :].split()  # after "pid (name) "
        pid = int(stat.parent.name)
        tree[int(fields[1])].append(pid)
        used[pid] = int(fields[11]) + int(fields[12])
    if not used:
        return None
    ticks, pending = 0, list(roots)
    while pending:
        pid = pending.pop()
        ticks += used.get(pid, 0)
        pending.extend(tree.get(pid, []))
    return ticks / os.sysconf("SC_CLK_TCK")


def own_cpu_seconds() -> float:
    """CPU time of this process: the clients."""
    usage = resource.getrusage(resource.RUSAGE_SELF)
    return usage.ru_utime + usage.ru_stime


@dataclass
class Service:
    """A running API with its workers: where to reach it, and which processes are whose."""

    url: str
    api: list[int]
    workers: list[int]

    def cpu(self) -> dict[str, float] | None:
        """CPU seconds so far of the API and the workers, if any (None without /proc)."""
        api, workers = cpu_seconds(self.api), cpu_seconds(self.workers)
        if api is None or workers is None:
            return None
        return {"API": api, "workers": workers} if self.workers else {"API": api}


def wait_until_answering(
    url: str, deadline: float, children: list[subprocess.Popen[bytes]]
) -> None:
    """Until ``url`` answers 200; RuntimeError past ``deadline`` or once a child has ended."""
    while True:
        try:
            if httpx.get(url, timeout=5).status_code == 200:
                return
        except httpx.TransportError:
            pass
        if time.monotonic() > deadline or any(c.poll() is not None for c in children):
            raise RuntimeError(f"{url} did not answer")
        time.sleep(0.1)


def stop(children: list[subprocess.Popen[bytes]]) -> None:
    """SIGTERM each child, and SIGKILL those still running 30 s later."""
    for child in children:
        child.send_signal(signal.SIGTERM)
    for child in children:
        try:
            child.wait(timeout=30)
        except subprocess.TimeoutExpired:
            child.kill()


@contextmanager
def running_service(
    database_url: str | None, workers: int, api_processes: int = 1
) -> Iterator[Service]:
    """``api_processes`` API processes (uvicorn --workers) and ``workers`` worker processes on
    ``database_url`` (a fresh SQLite file if None)."""
    workdir = Path(tempfile.mkdtemp(prefix="nanonav-load-"))
    database_url = database_url or f"sqlite:///{workdir / 'nanonav.db'}"
    from nanonav.store.migrate import upgrade

    upgrade(database_url)
    port = free_port()
    env = {
        **{k: v for k, v in os.environ.items() if k not in {"DATABASE_URL", "HOST", "PORT"}},
        "NANONAV_DATABASE_URL": database_url,
    }
    names = ["api", *(f"worker-{i}" for i in range(workers))]
    logs = {name: open(workdir / f"{name}.log", "wb") for name in names}  # noqa: SIM115
    api = [sys.executable, "-m", "uvicorn", "service.app:create_app", "--factory", "--port",
           str(port), "--log-level", "warning", "--workers", str(api_processes)]  # fmt: skip
    commands = [api] + [[sys.executable, "-m", "worker"]] * workers
    children = [
        subprocess.Popen(command, env=env, stdout=logs[name], stderr=subprocess.STDOUT)
        for name, command in zip(names, commands, strict=True)
    ]
    url = f"http://127.0.0.1:{port}"
    try:
        deadline = time.monotonic() + 180
        while not all(b" ready on " in (workdir / f"{n}.log").read_bytes() for n in names[1:]):
            if time.monotonic() > deadline or any(c.poll() is not None for c in children):
                raise RuntimeError(f"the workers did not start; see {workdir}")
            time.sleep(0.1)
        wait_until_answering(f"{url}/healthz", deadline, children)
        yield Service(url, api=[children[0].pid], workers=[c.pid for c in children[1:]])
    finally:
        stop(children)
        for log in logs.values():
            log.close()


@dataclass
class Tally:
    """What the clients saw: the time of every answer per route, and what went wrong."""

    times: dict[str, list[float]] = field(default_factory=lambda: defaultdict(list))
    errors: dict[str, int] = field(default_factory=lambda: defaultdict(int))
    jobs_ended: int = 0
    sent: int = 0

    def add(self, other: Tally) -> None:
        """Count in what another process's clients saw."""
        for route, times in other.times.items():
            self.times[route].extend(times)
        for what, count in other.errors.items():
            self.errors[what] += count
        self.jobs_ended += other.jobs_ended
        self.sent += other.sent


async def client_loop(
    http: httpx.AsyncClient, tally: Tally, seed: int, stop_at: float, pause: float, cap: int
) -> None:
    async def call(route: str, method: str, path: str, **kwargs: Any) -> httpx.Response | None:
        tally.sent += 1
        started = time.perf_counter()
        try:
            response = await http.request(method, path, **kwargs)
        except httpx.HTTPError as error:
            tally.errors[f"{route}: {type(error).__name__}"] += 1
            return None
        tally.times[route].append(time.perf_counter() - started)
        if not response.is_success:
            tally.errors[f"{route}: {response.status_code}"] += 1
            return None
        return response

    def going() -> bool:
        return time.monotonic() < stop_at and tally.sent < cap

    while going():
        submitted = await call(SUBMIT, "POST", "/jobs", json={**SMALL, "seed": seed})
        seed += 1_000
        if submitted is None:
            await asyncio.sleep(pause)
            continue
        path = f"/jobs/{submitted.json()['id']}"
        while going():
            await asyncio.sleep(pause)
            if not going():  # the cap may have been reached while this client slept
                break
            polled = await call(POLL, "GET", path)
            if polled is not None and polled.json()["status"] in ENDED:
                tally.jobs_ended += 1
                break


async def load(
    url: str, seeds: Sequence[int], duration: float, pause: float, cap: int
) -> tuple[Tally, float, float]:
    """One client per seed, each with a connection of its own, as separate programs would be
    (one shared pool of 50 connections costs httpx more CPU per request than the API spends).
    What they saw, and the seconds and CPU seconds the load took, once the clients were made."""
    tally = Tally()
    https = [httpx.AsyncClient(base_url=url, timeout=30) for _ in seeds]
    try:
        started, cpu = time.monotonic(), own_cpu_seconds()
        stop_at = started + duration
        await asyncio.gather(*(client_loop(http, tally, seed, stop_at, pause, cap)
                               for seed, http in zip(seeds, https, strict=True)))  # fmt: skip
        return tally, time.monotonic() - started, own_cpu_seconds() - cpu
    finally:
        for http in https:
            await http.aclose()


def client_process(
    url: str,
    seeds: Sequence[int],
    duration: float,
    pause: float,
    cap: int,
    start: Barrier,
    results: multiprocessing.Queue[tuple[Tally, float, float]],
) -> None:
    """Some of the clients, in a process of their own; they start when every process can."""
    start.wait()
    results.put(asyncio.run(load(url, seeds, duration, pause, cap)))


def drive(
    url: str, clients: int, processes: int, duration: float, pause: float, cap: int
) -> tuple[Tally, float, float]:
    """``clients`` clients over ``processes`` processes: what they saw, the seconds it took,
    and the CPU seconds the clients used."""
    if processes == 1:
        return asyncio.run(load(url, range(clients), duration, pause, cap))
    spawn = multiprocessing.get_context("spawn")
    start = spawn.Barrier(processes + 1)
    results: multiprocessing.Queue[tuple[Tally, float, float]] = spawn.Queue()
    children = [
        spawn.Process(
            target=client_process,
            args=(url, seeds, duration, pause, cap // processes, start, results),
        )
        for seeds in (range(clients)[i::processes] for i in range(processes))
    ]
    for child in children:
        child.start()
    try:
        start.wait(timeout=120)
        tally, elapsed, cpu = Tally(), 0.0, 0.0
        for _ in children:
            part, seconds, cpu_seconds = results.get(timeout=duration + 120)
            tally.add(part)
            elapsed, cpu = max(elapsed, seconds), cpu + cpu_seconds
    finally:
        for child in children:
            child.join(timeout=30)
            if child.is_alive():
                child.kill()
    return tally, elapsed, cpu


async def nothing(scope: dict[str, Any], receive: Any, send: Any) -> None:
    """An ASGI server that does nothing: a job is queued at once and ends on its tenth poll,
    answered with a body the size of a real job's."""
    if scope["type"] == "lifespan":
        while (await receive())["type"] != "lifespan.shutdown":
            await send({"type": "lifespan.startup.complete"})
        await send({"type": "lifespan.shutdown.complete"})
        return
    while (await receive()).get("more_body", False):
        pass
    if scope["method"] == "POST":
        job = next(_IDS)
        _POLLS[job] = 0
        status, answer = 202, {"id": job, "status": "queued"}
    else:
        status = 200
        job = int(scope["path"].rsplit("/", 1)[-1])
        _POLLS[job] = _POLLS.get(job, 0) + 1
        ended = _POLLS[job] >= 10
        answer = {"id": job, "status": "succeeded" if ended else "queued", "padding": "x" * 1100}
    body = json.dumps(answer).encode()
    headers = [(b"content-type", b"application/json"), (b"content-length", b"%d" % len(body))]
    await send({"type": "http.response.start", "status": status, "headers": headers})
    await send({"type": "http.response.body", "body": body})


_IDS = itertools.count(1)
_POLLS: dict[int, int] = {}


@contextmanager
def null_service() -> Iterator[Service]:
    """:func:`nothing`, served by uvicorn as the API is."""
    port = free_port()
    here = Path(__file__).resolve().parent
    command = [sys.executable, "-m", "uvicorn", f"{Path(__file__).stem}:nothing", "--app-dir",
               str(here), "--port", str(port), "--log-level", "warning"]  # fmt: skip
    child = subprocess.Popen(command)
    url = f"http://127.0.0.1:{port}"
    try:
        wait_until_answering(f"{url}/jobs/0", time.monotonic() + 60, [child])
        yield Service(url, api=[child.pid], workers=[])
    finally:
        stop([child])


def report(tally: Tally, elapsed: float, title: str, cpu: dict[str, float] | None) -> None:
    answered = sum(len(times) for times in tally.times.values())
    print(title)
    print(f"  {answered / elapsed:.1f} requests/s ({answered} answered), "
          f"{tally.jobs_ended} jobs ended")  # fmt: skip
    for route in (SUBMIT, POLL):
        times = tally.times.get(route) or [float("nan")]
        print(f"  {route:<16} n {len(tally.times.get(route, [])):>6}   "
              f"p50 {1000 * percentile(times, 50):.1f} ms   "
              f"p99 {1000 * percentile(times, 99):.1f} ms   "
              f"max {1000 * max(times):.1f} ms")  # fmt: skip
    if cpu is not None:
        # What each part kept busy, in cores: the clients, the API and the workers share the
        # machine, and an answer waits while the API has no core.
        shares = ", ".join(f"{name} {seconds / elapsed:.2f}" for name, seconds in cpu.items())
        print(f"  cores busy on average, of {os.cpu_count()}: {shares}")
    print(f"  errors: {sum(tally.errors.values())}")
    for what, count in sorted(tally.errors.items()):
        print(f"    {what}: {count}")


def measure(service: Service, args: argparse.Namespace) -> tuple[Tally, float, dict[str, float]]:
    """The clients' load on ``service``: what they saw, how long, and the cores each part used."""
    before = service.cpu()
    tally, elapsed, clients_cpu = drive(service.url, args.clients, args.client_processes,
                                        args.duration, args.pause, args.max_requests)  # fmt: skip
    after = service.cpu()
    cpu: dict[str, float] = {}
    if before is not None and after is not None:
        cpu = {name: after[name] - before[name] for name in after}
    return tally, elapsed, {**cpu, "clients": clients_cpu}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration", type=float, default=60.0, help="seconds of load (60)")
    parser.add_argument("--clients", type=int, default=50, help="concurrent clients (50)")
    parser.add_argument("--pause", type=float, default=0.1,
                        help="seconds a client waits between two polls (0.1)")  # fmt: skip
    parser.add_argument("--max-requests", type=int, default=1_000_000,
                        help="stop after this many requests (1,000,000)")  # fmt: skip
    parser.add_argument("--client-processes", type=int, default=1,
                        help="processes the clients are spread over (1)")  # fmt: skip
    parser.add_argument("--floor", action="store_true",
                        help="first load a server that does nothing, same clients")  # fmt: skip
    parser.add_argument("--database-url", help="the store to use (a fresh SQLite file)")
    parser.add_argument("--api-processes", type=int, default=1,
                        help="API processes, as uvicorn --workers (1)")  # fmt: skip
    args = parser.parse_args(argv)
    if not 1 <= args.client_processes <= args.clients:
        parser.error("--client-processes must be between 1 and --clients")
    clients = f"{args.clients} clients in {args.client_processes} process(es)"
    failed = False
    if args.floor:
        with null_service() as service:
            tally, elapsed, cpu = measure(service, args)
        report(tally, elapsed, f"floor: {clients} for {elapsed:.1f} s on a server that does "
               "nothing", cpu)  # fmt: skip
        failed = bool(tally.errors)
    backend = "SQLite" if args.database_url is None else args.database_url.split(":", 1)[0]
    with running_service(args.database_url, workers=2, api_processes=args.api_processes) as service:
        tally, elapsed, cpu = measure(service, args)
    report(tally, elapsed, f"load: {clients} for {elapsed:.1f} s on {backend}, "
           f"{args.api_processes} API process(es), two workers", cpu)  # fmt: skip
    return 0 if not (tally.errors or failed) else 1


if __name__ == "__main__":
    raise SystemExit(main())
