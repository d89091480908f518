"""The job service's speed, measured on real processes: one uvicorn API, two workers, SQLite.

Prints: submit-to-succeeded latency of a small job (p50, p95) with idle workers; jobs per second
through the API and two workers; and the latency of ``GET /jobs/{id}`` while both workers are busy.

    .venv/bin/python benchmarks/service.py [--latency-jobs 20] [--throughput-jobs 40]
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
from pathlib import Path
from typing import Any

import httpx

SMALL: dict[str, Any] = {"robots": {"count": 1}, "learning": {"episodes": 1, "max_steps": 50}}


def percentile(values: list[float], q: float) -> float:
    ordered = sorted(values)
    index = min(len(ordered) - 1, max(0, round(q / 100 * (len(ordered) - 1))))
    return ordered[index]


def free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        port: int = sock.getsockname()[1]
        return port


def wait_succeeded(client: httpx.Client, job_id: int, timeout: float = 300) -> None:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        status = client.get(f"/jobs/{job_id}").json()["status"]
        if status == "succeeded":
            return
        if status in {"failed", "cancelled"}:
            raise RuntimeError(f"job {job_id} ended {status}")
        time.sleep(0.005)
    raise TimeoutError(f"job {job_id} did not finish")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--latency-jobs", type=int, default=20)
    parser.add_argument("--throughput-jobs", type=int, default=40)
    args = parser.parse_args()

    workdir = Path(tempfile.mkdtemp(prefix="nanonav-bench-"))
    database_url = f"sqlite:///{workdir / 'nanonav.db'}"
    port = free_port()
    env = {
        **{k: v for k, v in os.environ.items() if k not in {"DATABASE_URL", "HOST", "PORT"}},
        "NANONAV_DATABASE_URL": database_url,
        "NANONAV_POLL_INTERVAL_S": "0.05",
    }
    from nanonav.store.migrate import upgrade

    upgrade(database_url)
    logs = [open(workdir / f"{name}.log", "wb") for name in ("api", "worker-0", "worker-1")]  # noqa: SIM115
    api = subprocess.Popen(
        [sys.executable, "-m", "uvicorn", "service.app:create_app", "--factory",
         "--port", str(port), "--log-level", "warning"],
        env=env, stdout=logs[0], stderr=subprocess.STDOUT,
    )  # fmt: skip
    workers = [
        subprocess.Popen(
            [sys.executable, "-m", "worker"], env=env, stdout=log, stderr=subprocess.STDOUT
        )
        for log in logs[1:]
    ]
    children = [api, *workers]
    try:
        deadline = time.monotonic() + 120
        while not all(b"ready" in (workdir / f"worker-{i}.log").read_bytes() for i in range(2)):
            if time.monotonic() > deadline:
                raise TimeoutError("the workers did not start")
            time.sleep(0.1)
        with httpx.Client(base_url=f"http://127.0.0.1:{port}", timeout=30) as client:
            while True:
                try:
                    if client.get("/healthz").status_code == 200:
                        break
                except httpx.TransportError:
                    time.sleep(0.1)
            run(client, args.latency_jobs, args.throughput_jobs)
    finally:
        for child in children:
            child.send_signal(signal.SIGTERM)
        for child in children:
            child.wait(timeout=30)
        for log in logs:
            log.close()


def run(client: httpx.Client, latency_jobs: int, throughput_jobs: int) -> None:
    print(f"scenario: {SMALL} (1 robot, 1 training episode + evaluation, 50 steps)")
    print(f"cores: {os.cpu_count()}, SQLite, 1 API process, 2 worker processes\n")

    latencies = []
    for seed in range(latency_jobs):
        started = time.perf_counter()
        response = client.post("/jobs", json={**SMALL, "seed": seed})
        wait_succeeded(client, response.json()["id"])
        latencies.append(time.perf_counter() - started)
    print(f"submit-to-succeeded latency, {latency_jobs} jobs one at a time:")
    print(f"  p50 {percentile(latencies, 50):.3f} s   p95 {percentile(latencies, 95):.3f} s")

    get_latencies: list[float] = []
    busy = threading.Event()

    def poll_while_busy(job_id: int) -> None:
        with httpx.Client(base_url=client.base_url, timeout=30) as reader:
            while not busy.is_set():
                started = time.perf_counter()
                reader.get(f"/jobs/{job_id}").raise_for_status()
                get_latencies.append(time.perf_counter() - started)
                time.sleep(0.01)

    started = time.perf_counter()
    ids = [
        client.post("/jobs", json={**SMALL, "seed": 1000 + i}).json()["id"]
        for i in range(throughput_jobs)
    ]
    submitted = time.perf_counter() - started
    reader = threading.Thread(target=poll_while_busy, args=(ids[len(ids) // 2],))
    reader.start()
    for job_id in ids:
        wait_succeeded(client, job_id)
    elapsed = time.perf_counter() - started
    busy.set()
    reader.join()
    print(f"\nthroughput, {throughput_jobs} jobs submitted at once ({submitted:.2f} s to submit):")
    print(f"  {throughput_jobs / elapsed:.2f} jobs/s ({elapsed:.1f} s in all)")
    print(f"\nGET /jobs/{{id}} while both workers are busy, {len(get_latencies)} requests:")
    print(
        f"  p50 {1000 * percentile(get_latencies, 50):.1f} ms   "
        f"p95 {1000 * percentile(get_latencies, 95):.1f} ms   "
        f"p99 {1000 * percentile(get_latencies, 99):.1f} ms   "
        f"mean {1000 * statistics.fmean(get_latencies):.1f} ms"
    )


if __name__ == "__main__":
    main()
