"""Whether the API's memory stays bounded under a soak of drawing and fuzzing.

    python benchmarks/api_memory.py             # 12 rounds (a few minutes)
    python benchmarks/api_memory.py --quick     # 3 short rounds

One real API process (``nanonav api``) and one worker over a SQLite file; three finished jobs
and a study. Each round draws pictures that are never kept (heatmaps at a new slice and
resolution, each a fresh drawing), reads every other picture and every result view, and sends
a batch of fuzzed requests (bodies and query strings made by a seeded generator, valid and
invalid alike, to every POST and to the result routes). The API's resident memory (VmRSS) is
sampled after each round. Memory that is bounded levels off: the table shows each round, and the
last line the growth over the second half of the rounds next to that over the first half.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import os
import random
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import httpx

# The service benchmark's helpers: loaded from its path (``service`` is the API package).
_SPEC = importlib.util.spec_from_file_location(
    "service_benchmark", Path(__file__).resolve().parent / "service.py"
)
assert _SPEC is not None and _SPEC.loader is not None
service_benchmark = importlib.util.module_from_spec(_SPEC)
sys.modules["service_benchmark"] = service_benchmark
_SPEC.loader.exec_module(service_benchmark)

TINY: dict[str, Any] = {"robots": {"count": 3}, "learning": {"episodes": 3, "max_steps": 80}}
PLOTS = ("trajectory", "concentration", "learning", "qtable")
VIEWS = ("metrics", "qtable", "qtable?format=csv", "trajectory?stride=7", "trajectory?format=csv")
POSTS = ("/jobs", "/studies", "/policies")


def rss_mb(pid: int) -> float:
    """Resident memory of process ``pid``, MB."""
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024
    raise RuntimeError(f"no VmRSS for process {pid}")


@contextmanager
def api_and_worker() -> Iterator[
    tuple[subprocess.Popen[bytes], subprocess.Popen[bytes], str, Path]
]:
    """An API and a worker over a fresh SQLite file: both processes, the API's URL and the
    folder of the file and their logs."""
    from nanonav.store.migrate import upgrade

    workdir = Path(tempfile.mkdtemp(prefix="nanonav-memory-"))
    url = f"sqlite:///{workdir / 'nanonav.db'}"
    upgrade(url)
    port = service_benchmark.free_port()
    env = {
        **{k: v for k, v in os.environ.items() if not k.startswith("NANONAV_")},
        "NANONAV_DATABASE_URL": url,
        "NANONAV_POLL_INTERVAL_S": "0.05",
    }
    env.pop("DATABASE_URL", None)
    logs = [(workdir / name).open("wb") for name in ("api.log", "worker.log")]
    api = subprocess.Popen(
        [sys.executable, "-m", "nanonav.cli", "api", "--port", str(port)],
        env=env, stdout=logs[0], stderr=subprocess.STDOUT,
    )  # fmt: skip
    worker = subprocess.Popen(
        [sys.executable, "-m", "worker"], env=env, stdout=logs[1], stderr=subprocess.STDOUT
    )
    try:
        yield api, worker, f"http://127.0.0.1:{port}", workdir
    finally:
        for process in (api, worker):
            stop(process)
        for log in logs:
            log.close()


def stop(process: subprocess.Popen[bytes]) -> None:
    process.terminate()
    try:
        process.wait(timeout=30)
    except subprocess.TimeoutExpired:
        process.kill()
        process.wait()


def wait_until(client: httpx.Client, path: str, done: str, timeout_s: float = 300) -> None:
    deadline = time.monotonic() + timeout_s
    while True:
        try:
            if client.get(path).json().get("status") == done:
                return
        except (httpx.TransportError, ValueError):
            pass
        if time.monotonic() > deadline:
            raise TimeoutError(f"{path} never became {done}")
        time.sleep(0.1)


def fuzzed_value(rng: random.Random, depth: int = 0) -> Any:
    """A JSON value of any kind, extremes of numbers and text included."""
    kind = rng.randrange(9 if depth < 3 else 6)
    if kind == 0:
        return rng.choice([0, -1, 1, 2**53, -(2**63), 10**400, 5e-324, 1.7e308, 1e-310])
    if kind == 1:
        return rng.uniform(-1e6, 1e6)
    if kind == 2:
        return "".join(chr(rng.randrange(1, 0x2FFF)) for _ in range(rng.randrange(40)))
    if kind == 3:
        return rng.choice([True, False, None])
    if kind == 4:
        return rng.choice(
            ["lattice", "active_brownian", "q_learning", "policy-1", "tumour-nanorobots"]
        )
    if kind == 5:
        return "x" * rng.randrange(10_000)
    if kind == 6:
        return [fuzzed_value(rng, depth + 1) for _ in range(rng.randrange(6))]
    keys = ["robots", "count", "physics", "viscosity_mpa_s", "robot_radius_um", "learning",
            "episodes", "grid", "seeds", "base", "states", "actions", "values", "name"]  # fmt: skip
    return {rng.choice(keys): fuzzed_value(rng, depth + 1) for _ in range(rng.randrange(1, 6))}


def fuzz(
    client: httpx.Client, rng: random.Random, requests: int, job_ids: list[int]
) -> dict[int, int]:
    """``requests`` fuzzed requests; how many got each status."""
    statuses: dict[int, int] = {}
    for _ in range(requests):
        if rng.random() < 0.6:
            body = json.dumps(fuzzed_value(rng), allow_nan=False)
            response = client.post(
                rng.choice(POSTS), content=body, headers={"Content-Type": "application/json"}
            )
        else:
            job = rng.choice(job_ids)
            stride = rng.choice([0, 1, -5, 10**30, "x"])
            query = f"stride={stride}&format={rng.choice(['json', 'npz', 'csv', 'png'])}"
            path = rng.choice(
                [f"/jobs/{job}/trajectory", f"/jobs/{job}/qtable", f"/jobs/{job}/heatmap.png"]
            )
            response = client.get(f"{path}?{query}")
        statuses[response.status_code] = statuses.get(response.status_code, 0) + 1
    return statuses


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="3 short rounds")
    parser.add_argument("--rounds", type=int, default=12)
    args = parser.parse_args(argv)
    rounds = 3 if args.quick else args.rounds
    drawings, fuzzed = (2, 40) if args.quick else (12, 400)
    rng = random.Random(20261203)
    with (
        api_and_worker() as (api, worker, url, workdir),
        httpx.Client(base_url=url, timeout=120) as client,
    ):
        service_benchmark.wait_healthy(client, time.monotonic() + 120, workdir)
        job_ids = [client.post("/jobs", json={**TINY, "seed": s}).json()["id"] for s in range(3)]
        study = client.post(
            "/studies", json={"base": TINY, "grid": {"robots.count": [2, 3]}, "seeds": [1, 2]}
        )
        for job_id in job_ids:
            wait_until(client, f"/jobs/{job_id}", "succeeded")
        study_id = study.json()["id"]
        wait_until(client, f"/studies/{study_id}", "succeeded")
        stop(worker)  # what the fuzzing queues is not run: the API alone is measured
        size = client.get(f"/jobs/{job_ids[0]}").json()["scenario"]["space"]["size"]
        print(f"{'round':>5} {'pictures':>9} {'fuzzed':>7} {'5xx':>4} {'API RSS MB':>11}")
        print(f"{0:5d} {0:9d} {0:7d} {0:4d} {rss_mb(api.pid):11.1f}")
        samples = [rss_mb(api.pid)]
        for round_ in range(1, rounds + 1):
            drawn = 0
            for _ in range(drawings):
                job_id = rng.choice(job_ids)
                at = rng.uniform(-size / 2, size / 2)
                resolution = rng.randrange(20, 161)  # the route takes 20 to 400
                path = f"/jobs/{job_id}/heatmap.png?plane=all&at={at:.4f}&resolution={resolution}"
                client.get(path).raise_for_status()
                drawn += 1
            for job_id in job_ids:
                for plot in PLOTS:
                    client.get(f"/jobs/{job_id}/plots/{plot}.png").raise_for_status()
                for view in VIEWS:
                    client.get(f"/jobs/{job_id}/{view}").raise_for_status()
            client.get(f"/studies/{study_id}/results.csv").raise_for_status()
            statuses = fuzz(client, rng, fuzzed, job_ids)
            errors = sum(n for status, n in statuses.items() if status >= 500)
            samples.append(rss_mb(api.pid))
            print(f"{round_:5d} {drawn:9d} {fuzzed:7d} {errors:4d} {samples[-1]:11.1f}")
    half = len(samples) // 2
    print(
        f"API RSS: {samples[0]:.1f} MB at the start, {max(samples):.1f} MB at most; growth over "
        f"rounds 0-{half}: {samples[half] - samples[0]:+.1f} MB, over rounds {half}-{rounds}: "
        f"{samples[-1] - samples[half]:+.1f} MB"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
