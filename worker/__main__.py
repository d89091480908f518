"""``python -m worker [--concurrency N] [--train]``: run jobs from the store the settings name
(with ``--train`` also those that train a network)."""

from __future__ import annotations

import argparse
import importlib.util
import logging

from nanonav.settings import Settings
from worker.loop import LOG_FORMAT, exit_at_once, supervise

TRAINS_WITHOUT_TORCH = (
    "--train needs the rl extra, which this environment lacks: pip install torch==2.13.0 "
    "'nanonav[rl]' (or make run TRAIN=1)"
)


def main(argv: list[str] | None = None) -> None:
    settings = Settings()
    parser = argparse.ArgumentParser(prog="python -m worker", description=__doc__)
    parser.add_argument(
        "--concurrency",
        type=int,
        default=settings.worker_concurrency,
        help="worker processes to run (default: NANONAV_WORKER_CONCURRENCY or 1)",
    )
    parser.add_argument(
        "--train",
        action="store_true",
        default=settings.worker_trains,
        help="also claim the jobs that train a network (needs the rl extra; default: "
        "NANONAV_WORKER_TRAINS)",
    )
    args = parser.parse_args(argv)
    if args.concurrency < 1:
        parser.error("--concurrency must be at least 1")
    if args.train and importlib.util.find_spec("torch") is None:
        parser.error(TRAINS_WITHOUT_TORCH)
    settings = settings.model_copy(update={"worker_trains": args.train})
    logging.basicConfig(level=logging.INFO, format=LOG_FORMAT)
    supervise(settings, args.concurrency)
    exit_at_once()


if __name__ == "__main__":
    main()
