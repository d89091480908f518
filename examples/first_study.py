"""A first study: does a learning robot find its cell faster than one that climbs the gradient?
Queue both policies on the same seeds, wait, print each one's mean with its 95 % interval and
the paired difference, and save the table and a picture.

    make run                        # in another terminal: the API and a worker
    python examples/first_study.py  # NANONAV_URL names another server
"""

from __future__ import annotations

import sys
from pathlib import Path

from nanonav.client import ApiError, Client, ServerUnreachable

STUDY = {
    "name": "first study: q_learning against gradient",
    "base": {"preset": "paper-single", "learning": {"episodes": 20}},
    "grid": {"robots.policy": ["gradient", "q_learning"]},  # the first is the baseline
    "seeds": [1, 2, 3, 4, 5],  # every policy meets the same worlds on each seed
    "compare": "robots.policy",
}
METRICS = ("success_rate", "total_steps")
OUT = Path("first-study")


def shown(value: float | None, form: str = ".3f") -> str:
    """A number as ``form`` writes it; ``-`` where the study has none (no spread, no test)."""
    return "-" if value is None else format(value, form)


def main() -> int:
    with Client() as api:  # $NANONAV_URL, else http://127.0.0.1:8000
        try:
            next(api.jobs(limit=1), None)  # fails at once if nothing answers there
            study = api.submit_study(STUDY)
            print(f"study {study.id}: {study.jobs.total} jobs at {api.url}/ui/studies/{study.id}")
            study = api.wait_study(study.id, timeout_s=600)
            print(f"study {study.id} {study.status}")
            for point in study.points:
                for name in METRICS:
                    m = point.metrics[name]
                    print(
                        f"{point.values['robots.policy']:>12} {name:>13}: {shown(m.mean)} "
                        f"[{shown(m.ci_low)}, {shown(m.ci_high)}] over {m.n} seeds"
                    )
            for comparison in study.comparisons:
                for name in METRICS:
                    d = comparison.metrics[name]
                    print(
                        f"{comparison.method} - {comparison.baseline} {name}: "
                        f"{shown(d.mean_difference, '+.3f')} [{shown(d.ci_low, '+.3f')}, "
                        f"{shown(d.ci_high, '+.3f')}], Wilcoxon p {shown(d.p_value)}"
                    )
            OUT.mkdir(exist_ok=True)
            table = api.write_study_csv(study.id, OUT / "results.csv")
            picture = OUT / "total_steps.png"
            picture.write_bytes(api.study_picture(study.id, "total_steps"))
            print(f"table: {table}, picture: {picture}")
            return 0 if study.status == "succeeded" else 1
        except ServerUnreachable as error:
            print(f"{error}\nstart one with `make run`, or set NANONAV_URL", file=sys.stderr)
            return 1
        except ApiError as error:
            print(error, file=sys.stderr)
            return 1


if __name__ == "__main__":
    sys.exit(main())
