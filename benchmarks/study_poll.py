"""A large running study, polled: ``GET /studies/{id}`` latency under ``wrk``, on real processes.

A study of ``--jobs`` jobs (2,000, the largest a server takes by default) over a 2 x 2 grid is
stored with ``--finished`` of them (half) already succeeded, each with metrics drawn at random.
One API process serves it on SQLite while ``wrk`` (a C client, so the clients cost the two
cores little) keeps ``--connections`` connections (50) polling it for ``--duration`` seconds
(20), each waiting ``--poll-interval-s`` (1 s; 0 for none) between polls. Meanwhile a thread
here finishes ``--finishing-per-s`` more jobs a second (5), so the study changes as a running
one does. Prints wrk's latency percentiles and requests per second.

    apt-get install wrk
    .venv/bin/python benchmarks/study_poll.py [--jobs 2000] [--finished 1000] [--duration 20]
                                              [--connections 50] [--poll-interval-s 1]
                                              [--finishing-per-s 5]
"""

from __future__ import annotations

import argparse
import importlib.util
import random
import re
import shutil
import subprocess
import sys
import tempfile
import threading
from pathlib import Path

# The load benchmark's processes: loaded from its path.
_SPEC = importlib.util.spec_from_file_location(
    "load_benchmark", Path(__file__).resolve().parent / "load.py"
)
assert _SPEC is not None and _SPEC.loader is not None
load_benchmark = importlib.util.module_from_spec(_SPEC)
sys.modules["load_benchmark"] = load_benchmark
_SPEC.loader.exec_module(load_benchmark)

from nanonav.store import JobStore, StudyJob, StudyStore  # noqa: E402
from nanonav.store.migrate import upgrade  # noqa: E402
from nanonav.store.queue import Outcome  # noqa: E402
from nanonav.studies.report import METRICS  # noqa: E402

GRID = {"robots.policy": ["q_learning", "gradient"], "obstacles.count": [0, 10]}


def stored_study(database_url: str, jobs: int) -> int:
    """A study of ``jobs`` queued jobs, stored as POST /studies stores one; its id."""
    upgrade(database_url)
    store = JobStore.from_url(database_url)
    try:
        seeds = list(range(jobs // 4))
        spec = {"name": "polled", "base": {}, "grid": GRID, "seeds": seeds,
                "compare": "robots.policy"}  # fmt: skip
        study_jobs = [
            StudyJob(scenario={"seed": seed}, robot_steps=1, episodes=1, point=point, seed=seed)
            for seed in seeds
            for point in range(4)
        ]
        return StudyStore(store.engine).create(name="polled", spec=spec, jobs=study_jobs).id
    finally:
        store.close()


def finish(store: JobStore, rng: random.Random, count: int) -> int:
    """Claim and succeed up to ``count`` queued jobs with random metrics; how many."""
    done = 0
    for _ in range(count):
        claim = store.claim("benchmark", lease_s=60)
        if claim is None:
            break
        metrics = {key: rng.random() for key in METRICS}
        outcome = Outcome(completed=True, metrics={"summary": metrics}, trajectory=None,
                          qtable=None, study_metrics=metrics)  # fmt: skip
        store.finish(claim, outcome)
        done += 1
    return done


def wrk(url: str, connections: int, duration_s: float, interval_s: float = 0.0) -> str:
    """wrk's report of ``connections`` connections asking for ``url``, each waiting
    ``interval_s`` after every answer (none: as fast as the server answers)."""
    command = ["wrk", "--latency", "-t", "2", "-c", str(connections), "-d", f"{duration_s:g}s",
               "--timeout", "10s"]  # fmt: skip
    with tempfile.NamedTemporaryFile("w", suffix=".lua") as script:
        if interval_s > 0:
            script.write(f"function delay()\n  return {interval_s * 1000:.0f}\nend\n")
            script.flush()
            command += ["-s", script.name]
        return subprocess.run([*command, url], check=True, capture_output=True, text=True).stdout


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--jobs", type=int, default=2000, help="jobs in the study (2000)")
    parser.add_argument("--finished", type=int, default=1000, help="of them succeeded (1000)")
    parser.add_argument("--duration", type=float, default=20.0, help="seconds of polling (20)")
    parser.add_argument("--connections", type=int, default=50, help="wrk connections (50)")
    parser.add_argument("--poll-interval-s", type=float, default=1.0,
                        help="each connection's wait between polls; 0: none (1)")  # fmt: skip
    parser.add_argument("--finishing-per-s", type=float, default=5.0,
                        help="jobs finished per second while polling (5)")  # fmt: skip
    args = parser.parse_args(argv)
    if shutil.which("wrk") is None:
        print("wrk is not installed: apt-get install wrk", file=sys.stderr)
        return 2
    workdir = Path(tempfile.mkdtemp(prefix="nanonav-study-poll-"))
    database_url = f"sqlite:///{workdir / 'nanonav.db'}"
    study = stored_study(database_url, args.jobs)
    store = JobStore.from_url(database_url)
    rng = random.Random(0)
    finish(store, rng, args.finished)
    stopped = threading.Event()

    def keep_finishing() -> None:
        period = 1.0 / args.finishing_per_s
        while not stopped.wait(period):
            finish(store, rng, 1)

    with load_benchmark.running_service(database_url, workers=0) as service:
        url = f"{service.url}/studies/{study}"
        wrk(url, 2, 2)  # warm up: the first answers import and compile
        finisher = threading.Thread(target=keep_finishing, daemon=True)
        if args.finishing_per_s > 0:
            finisher.start()
        cpu_before = service.cpu()
        output = wrk(url, args.connections, args.duration, args.poll_interval_s)
        cpu_after = service.cpu()
        stopped.set()
    store.close()
    latency = dict(re.findall(r"^\s*(50|75|90|99)%\s+(\S+)", output, re.MULTILINE))
    rate = re.search(r"Requests/sec:\s+(\S+)", output)
    errors = re.search(r"Non-2xx or 3xx responses: (\d+)", output)
    timeouts = re.search(r"timeout (\d+)", output)
    print(f"GET /studies/{{id}} of a {args.jobs}-job study, {args.connections} wrk connections "
          f"polling every {args.poll_interval_s:g} s for {args.duration:g} s, "
          f"{args.finishing_per_s:g} jobs finishing per s")  # fmt: skip
    print(f"  p50 {latency.get('50')}  p75 {latency.get('75')}  p90 {latency.get('90')}  "
          f"p99 {latency.get('99')}  req/s {rate.group(1) if rate else '?'}  "
          f"non-2xx {errors.group(1) if errors else 0}  "
          f"timeouts {timeouts.group(1) if timeouts else 0}")  # fmt: skip
    if cpu_before and cpu_after:
        busy = (cpu_after["API"] - cpu_before["API"]) / args.duration
        print(f"  API process busy {busy:.2f} cores")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
