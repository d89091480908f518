"""Draws the pictures the README and the site show, from the code as it is, so that they show
what a job draws today (the transition band's curves are drawn by
``benchmarks/transition_band.py report`` from its runs).

    python docs/_scripts/images.py     # write docs/images/paper-swarm-trajectory.png
"""

from __future__ import annotations

from pathlib import Path

from nanonav.engine import simulate
from nanonav.pictures.job.trajectory import trajectory_png
from nanonav.scenario import preset_scenario

IMAGES = Path(__file__).resolve().parents[1] / "images"


def main() -> None:
    # the paper's swarm at seed 3: fifteen robots, ten obstacles, two drifting cells
    result = simulate(preset_scenario("paper-swarm", seed=3))
    written = IMAGES / "paper-swarm-trajectory.png"
    written.write_bytes(trajectory_png(result))
    print(f"wrote {written.relative_to(IMAGES.parents[1])}")


if __name__ == "__main__":
    main()
