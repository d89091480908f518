"""The job service's speed, measured on real processes: one uvicorn API, two workers, SQLite.

Prints, for a tiny job (1 robot, 1 training episode + the evaluation, 50 steps):
- submit-to-succeeded latency, one job at a time (p50, p95);
- throughput: jobs per second through the API and the workers (two, or --workers), all at once;
- pictures: the first request of each (drawn then), and later requests (read from the store);
- ``GET /jobs/{id}`` and ``POST /jobs`` latency while the workers run longer jobs;
- the database's growth per tiny job;
- a study of ``paper-single`` defaults x 2 policies x 100 seeds (200 jobs): wall time, jobs/s.

    .venv/bin/python benchmarks/service.py [--quick] [--throughput-jobs 500]
"""

from __future__ import annotations

import argparse
import os
import signal
import socket
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable, Iterator
from concurrent.futures import ThreadPoolExecutor
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import httpx

TINY: dict[str, Any] = {"robots": {"count": 1}, "learning": {"episodes": 1, "max_steps": 50}}
# A few seconds of simulation each: keeps the workers busy while latency is measured.
BUSY: dict[str, Any] = {"preset": "paper-swarm", "learning": {"episodes": 2000}}
PICTURES = (
    "heatmap.png?plane=xy",
    "heatmap.png?plane=all",
    "plots/trajectory.png",
    "plots/concentration.png",
    "plots/learning.png",
)
SUBMITTERS = 8


def percentile(values: list[float], q: float) -> float:
    ordered = sorted(values)
    index = min(len(ordered) - 1, max(0, round(q / 100 * (len(ordered) - 1))))
    return ordered[index]


def spread(values: list[float], unit: float = 1000.0, suffix: str = "ms") -> str:
    """p50, p95, p99 and max of ``values`` (seconds), shown in ``suffix``."""
    return "   ".join(
        f"{name} {unit * value:.1f} {suffix}"
        for name, value in (
            ("p50", percentile(values, 50)),
            ("p95", percentile(values, 95)),
            ("p99", percentile(values, 99)),
            ("max", max(values)),
        )
    )


def free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        port: int = sock.getsockname()[1]
        return port


def wait_healthy(client: httpx.Client, deadline: float, workdir: Path) -> None:
    """Until the API's ``/healthz`` answers 200; TimeoutError past ``deadline``."""
    while True:
        try:
            if client.get("/healthz").status_code == 200:
                return
        except httpx.TransportError:
            pass
        if time.monotonic() > deadline:
            raise TimeoutError(f"the API did not start; see {workdir}")
        time.sleep(0.1)


@dataclass
class Service:
    client: httpx.Client
    database: Path


@contextmanager
def service(workers: int = 2) -> Iterator[Service]:
    """A migrated SQLite file, one API process and ``workers`` worker processes."""
    workdir = Path(tempfile.mkdtemp(prefix="nanonav-bench-"))
    database = workdir / "nanonav.db"
    database_url = f"sqlite:///{database}"
    port = free_port()
    env = {
        **{k: v for k, v in os.environ.items() if k not in {"DATABASE_URL", "HOST", "PORT"}},
        "NANONAV_DATABASE_URL": database_url,
        "NANONAV_POLL_INTERVAL_S": "0.05",
    }
    from nanonav.store.migrate import upgrade

    upgrade(database_url)
    names = ["api", *(f"worker-{i}" for i in range(workers))]
    logs = {name: open(workdir / f"{name}.log", "wb") for name in names}  # noqa: SIM115
    api = subprocess.Popen(
        [sys.executable, "-m", "uvicorn", "service.app:create_app", "--factory",
         "--port", str(port), "--log-level", "warning"],
        env=env, stdout=logs["api"], stderr=subprocess.STDOUT,
    )  # fmt: skip
    children = [api] + [
        subprocess.Popen(
            [sys.executable, "-m", "worker"], env=env, stdout=logs[n], stderr=subprocess.STDOUT
        )
        for n in names[1:]
    ]
    try:
        deadline = time.monotonic() + 120
        while not all(b"ready" in (workdir / f"{n}.log").read_bytes() for n in names[1:]):
            if time.monotonic() > deadline:
                raise TimeoutError(f"the workers did not start; see {workdir}")
            time.sleep(0.1)
        with httpx.Client(base_url=f"http://127.0.0.1:{port}", timeout=60) as client:
            wait_healthy(client, deadline, workdir)
            yield Service(client, database)
    finally:
        for child in children:
            child.send_signal(signal.SIGTERM)
        for child in children:
            child.wait(timeout=30)
        for log in logs.values():
            log.close()


def submit(client: httpx.Client, scenario: dict[str, Any]) -> int:
    response = client.post("/jobs", json=scenario)
    response.raise_for_status()
    job_id: int = response.json()["id"]
    return job_id


def wait_all(client: httpx.Client, ids: list[int], timeout: float = 600) -> None:
    """Until every job in ``ids`` has succeeded, reading the job list (one request a round)."""
    waiting = set(ids)
    deadline = time.monotonic() + timeout
    while waiting:
        if time.monotonic() > deadline:
            raise TimeoutError(f"{len(waiting)} jobs did not finish")
        for job_id in sorted(waiting):
            status = client.get(f"/jobs/{job_id}").json()["status"]
            if status in {"failed", "cancelled"}:
                raise RuntimeError(f"job {job_id} ended {status}")
            if status != "succeeded":
                break
            waiting.discard(job_id)
        if waiting:
            time.sleep(0.02)


def latency(client: httpx.Client, jobs: int) -> None:
    times = []
    for seed in range(jobs):
        started = time.perf_counter()
        job_id = submit(client, {**TINY, "seed": seed})
        wait_all(client, [job_id])
        times.append(time.perf_counter() - started)
    print(f"submit-to-succeeded latency, {jobs} tiny jobs one at a time:")
    print(f"  {spread(times)}")


def throughput(service: Service, jobs: int) -> list[int]:
    client = service.client
    size_before = service.database.stat().st_size
    started = time.perf_counter()
    with ThreadPoolExecutor(SUBMITTERS) as pool:
        scenarios = [{**TINY, "seed": 1000 + seed} for seed in range(jobs)]
        ids = list(pool.map(lambda scenario: submit(client, scenario), scenarios))
    submitted = time.perf_counter() - started
    wait_all(client, ids)
    elapsed = time.perf_counter() - started
    wal = service.database.with_name(service.database.name + "-wal")
    client.get("/healthz")
    grown = service.database.stat().st_size - size_before
    print(f"\nthroughput, {jobs} tiny jobs submitted at once by {SUBMITTERS} clients:")
    print(f"  {jobs / elapsed:.1f} jobs/s: {elapsed:.2f} s from the first submission to the last")
    print(f"  job's success; {submitted:.2f} s to submit them ({jobs / submitted:.0f} per second)")
    wal_size = wal.stat().st_size if wal.exists() else 0
    print(
        f"  database growth: {grown / jobs / 1024:.1f} KiB per job "
        f"(not counting {wal_size / 1e6:.1f} MB of write-ahead log not yet checkpointed)"
    )
    return ids


def pictures(client: httpx.Client, job_id: int, repeats: int) -> None:
    first: dict[str, float] = {}
    later: list[float] = []
    for path in PICTURES:
        started = time.perf_counter()
        response = client.get(f"/jobs/{job_id}/{path}")
        first[path] = time.perf_counter() - started
        response.raise_for_status()
    for _ in range(repeats):
        for path in PICTURES:
            started = time.perf_counter()
            client.get(f"/jobs/{job_id}/{path}").raise_for_status()
            later.append(time.perf_counter() - started)
    print(f"\npictures of job {job_id}, first request (drawn then) and later ones (read):")
    for path, seconds in first.items():
        print(f"  first  {path:<26} {1000 * seconds:7.1f} ms")
    print(f"  later  {len(later)} requests: {spread(later)}")


def while_busy(client: httpx.Client, tiny_job: int, busy_jobs: int) -> None:
    """Latency of reads and submissions while the workers run longer jobs."""
    ids = [submit(client, {**BUSY, "seed": seed}) for seed in range(busy_jobs)]
    gets: list[float] = []
    posts: list[float] = []
    done = threading.Event()

    def timed(samples: list[float], call: Callable[[], httpx.Response]) -> None:
        started = time.perf_counter()
        call().raise_for_status()
        samples.append(time.perf_counter() - started)

    def poll() -> None:
        with httpx.Client(base_url=client.base_url, timeout=60) as reader:
            while not done.is_set():
                timed(gets, lambda: reader.get(f"/jobs/{ids[0]}"))
                timed(gets, lambda: reader.get(f"/jobs/{tiny_job}"))
                time.sleep(0.01)

    reader = threading.Thread(target=poll)
    reader.start()
    started = time.perf_counter()
    while time.perf_counter() - started < 1.0:
        timed(posts, lambda: client.post("/jobs", json={**TINY, "seed": 5}))
        time.sleep(0.05)
    wait_all(client, ids)
    done.set()
    reader.join()
    print(f"\nwhile the workers run {busy_jobs} jobs of a few seconds ({BUSY}):")
    print(f"  GET /jobs/{{id}}  {len(gets)} requests: {spread(gets)}")
    print(f"  POST /jobs      {len(posts)} requests: {spread(posts)}")
    print(f"  mean GET {1000 * statistics.fmean(gets):.1f} ms")


def study(client: httpx.Client, seeds: int) -> None:
    body = {
        "name": "benchmark",
        "base": {"preset": "paper-single"},
        "grid": {"robots.policy": ["q_learning", "gradient"]},
        "replicates": seeds,
        "compare": "robots.policy",
    }
    started = time.perf_counter()
    response = client.post("/studies", json=body)
    response.raise_for_status()
    created = time.perf_counter() - started
    study_id = response.json()["id"]
    while (found := client.get(f"/studies/{study_id}").json())["status"] in {"queued", "running"}:
        time.sleep(0.05)
    elapsed = time.perf_counter() - started
    jobs = found["jobs"]["total"]
    print(f"\nstudy: paper-single defaults x 2 policies x {seeds} seeds ({jobs} jobs)")
    print(
        f"  {elapsed:.2f} s from POST to its report ({jobs / elapsed:.1f} jobs/s); "
        f"the POST took {1000 * created:.0f} ms"
    )
    steps = found["comparisons"][0]["metrics"]["total_steps"]
    print(
        f"  gradient - q_learning, total steps: {steps['mean_difference']:+.1f} "
        f"[{steps['ci_low']:+.1f}, {steps['ci_high']:+.1f}], p = {steps['p_value']:.3g}, "
        f"n = {steps['n']}"
    )


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--latency-jobs", type=int, default=20)
    parser.add_argument("--throughput-jobs", type=int, default=500)
    parser.add_argument("--picture-repeats", type=int, default=20)
    parser.add_argument("--busy-jobs", type=int, default=4)
    parser.add_argument("--study-seeds", type=int, default=100)
    parser.add_argument("--workers", type=int, default=2, help="worker processes (default 2)")
    parser.add_argument("--quick", action="store_true", help="a smoke run with few jobs")
    args = parser.parse_args(argv)
    if args.quick:
        args.latency_jobs, args.throughput_jobs = 3, 20
        args.picture_repeats, args.busy_jobs, args.study_seeds = 2, 0, 3
    print(f"tiny job: {TINY}")
    print(f"cores: {os.cpu_count()}, SQLite, 1 API process, {args.workers} worker processes\n")
    with service(args.workers) as running:
        latency(running.client, args.latency_jobs)
        ids = throughput(running, args.throughput_jobs)
        pictures(running.client, ids[-1], args.picture_repeats)
        if args.busy_jobs:
            while_busy(running.client, ids[0], args.busy_jobs)
        study(running.client, args.study_seeds)
    return 0


if __name__ == "__main__":
    sys.exit(main())
