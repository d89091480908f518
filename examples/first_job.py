"""A first job: queue a scenario on a running NanoNav service, wait for it, print its Table 1
and save two of its pictures.

    make run                      # in another terminal: the API and a worker
    python examples/first_job.py  # NANONAV_URL names another server
"""

from __future__ import annotations

import sys
from pathlib import Path

from nanonav.client import ApiError, Client, ServerUnreachable

# One robot, one cell, ten obstacles (the paper's Figure 1), 20 training episodes.
SCENARIO = {"preset": "paper-single", "seed": 7, "learning": {"episodes": 20}}
PICTURES = ("trajectory", "learning")
OUT = Path("first-job")


def main() -> int:
    with Client() as api:  # $NANONAV_URL, else http://127.0.0.1:8000
        try:
            next(api.jobs(limit=1), None)  # fails at once if nothing answers there
            job = api.submit(SCENARIO)
            print(f"job {job.id} queued at {api.url}/ui/jobs/{job.id}")
            job = api.wait(job.id, timeout_s=300)
            print(f"job {job.id} {job.status}")
            if job.status != "succeeded":
                print(job.error, file=sys.stderr)
                return 1
            summary = api.metrics(job.id)["summary"]
            for name in ("success_rate", "total_steps", "final_distance", "collisions"):
                print(f"{name:>16}: {summary[name]:.3f}")
            OUT.mkdir(exist_ok=True)
            for name in PICTURES:
                path = OUT / f"{name}.png"
                path.write_bytes(api.picture(job.id, name))
                print(f"{name:>16}: {path}")
        except ServerUnreachable as error:
            print(f"{error}\nstart one with `make run`, or set NANONAV_URL", file=sys.stderr)
            return 1
        except ApiError as error:
            print(error, file=sys.stderr)
            return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
