"""``python -m worker [--concurrency N]``: run jobs from the store the settings name."""

from __future__ import annotations

import argparse
import logging

from nanonav.settings import Settings
from worker.loop import LOG_FORMAT, exit_at_once, supervise


def main(argv: list[str] | None = None) -> None:
    settings = Settings()
    parser = argparse.ArgumentParser(prog="python -m worker", description=__doc__)
    parser.add_argument(
        "--concurrency",
        type=int,
        default=settings.worker_concurrency,
        help="worker processes to run (default: NANONAV_WORKER_CONCURRENCY or 1)",
    )
    args = parser.parse_args(argv)
    if args.concurrency < 1:
        parser.error("--concurrency must be at least 1")
    logging.basicConfig(level=logging.INFO, format=LOG_FORMAT)
    supervise(settings, args.concurrency)
    exit_at_once()


if __name__ == "__main__":
    main()
