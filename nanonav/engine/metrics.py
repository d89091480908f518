"""Table 1 of the paper, per robot and for the swarm, in every evaluation world; and the mean
over the worlds with its uncertainty.

Each metric means one thing, for one robot or for the swarm alike:

- ``total_steps``: Table 1's Total Steps. A robot's steps to reach a cell, ``max_steps`` if it
  did not; for a swarm, the median over its robots (so a failure counts as the step limit).
- ``mean_steps_to_reach``: the mean steps to reach over the robots that reached (none: null).
- ``episode_steps``: steps until every robot had reached, or the step limit.
- ``success_rate``: the share of robots that searched a cell out: reached it by their own move,
  or were met by a drifting cell while heading toward it. ``swept_up`` counts apart the robots a
  drifting cell met while they headed elsewhere (parked at a field maximum, say): they reached
  a cell, and stopped there, but did not find it.
- ``final_distance``: distance to the nearest cell at a robot's last step, mean over robots;
  ``final_distance_reached`` and ``final_distance_unreached`` split it (null when empty).
- ``average_distance``, ``average_concentration``: a robot's mean over its own steps (start
  included), then the mean over robots; the concentration is the true one at the robot.
- ``collisions``: moves blocked by an obstacle, summed over robots.
- ``path_efficiency``: straight distance from start to end over the path length, mean over
  robots; ``mean_return``: summed reward, mean over robots; ``duration_s``: wall time.

The swarm's numbers, given when robots take up space, cells can be treated or robots signal:

- ``robots_per_cell``: payloads delivered per cell, mean over cells; ``most_robots_on_a_cell``:
  the most any one cell received; ``bumps``: moves refused because another robot was in the
  way, summed over robots.
- with ``cells.capacity``: ``cells_treated`` (how many), ``treated_fraction`` (their share),
  ``time_to_treat_all`` (the step the last cell was treated, the step limit if one was left),
  ``never_delivered`` (the share of robots that delivered no payload).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from nanonav import stats
from nanonav.engine.state import (
    CELL_LOAD,
    CELL_TREATED_AT,
    EV_BUMPS,
    EV_COLLISIONS,
    EV_FINAL_DISTANCE,
    EV_PATH_LENGTH,
    EV_REACHED,
    EV_RETURN,
    EV_STEPS,
    EV_STRAIGHT,
    EV_SUM_CONCENTRATION,
    EV_SUM_DISTANCE,
    EV_SWEPT,
)

# The summary's numbers that are averaged over worlds (the counts are summed instead).
AVERAGED = (
    "total_steps",
    "mean_steps_to_reach",
    "episode_steps",
    "success_rate",
    "final_distance",
    "final_distance_reached",
    "final_distance_unreached",
    "average_distance",
    "average_concentration",
    "collisions",
    "path_efficiency",
    "mean_return",
    "duration_s",
)


# The swarm's numbers (see the module docstring), averaged over worlds where a run gives them.
SWARM = (
    "robots_per_cell",
    "most_robots_on_a_cell",
    "bumps",
    "cells_treated",
    "treated_fraction",
    "time_to_treat_all",
    "never_delivered",
)

SHARES_OF: dict[str, str] = {
    "success_rate": "robots",
    "never_delivered": "robots",
    "treated_fraction": "cells",
}
"""The metrics that are a share of trials in each evaluation world, and what the trials are: the
success rate is the share of a world's robots that reached a cell, the treated fraction the
share of its cells treated. Their intervals pool the trials (``nanonav.stats.describe_share``):
a world all of whose 20 robots reached a cell says more than one trial's 1."""

# Each averaged metric's range, which its interval keeps to (``nanonav.stats.describe``).
UNBOUNDED = None
PROPORTION = (0.0, 1.0)
NON_NEGATIVE = (0.0, math.inf)
RANGES: dict[str, tuple[float, float] | None] = {
    "success_rate": PROPORTION,
    "path_efficiency": PROPORTION,
    "mean_return": UNBOUNDED,
    "treated_fraction": PROPORTION,
    "never_delivered": PROPORTION,
    **{
        key: NON_NEGATIVE
        for key in AVERAGED + SWARM
        if key
        not in {"success_rate", "path_efficiency", "mean_return", "treated_fraction",
                "never_delivered"}
    },
}  # fmt: skip


def _efficiency(tallies: NDArray[np.float64]) -> NDArray[np.float64]:
    path = tallies[:, EV_PATH_LENGTH]
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(path > 0, tallies[:, EV_STRAIGHT] / path, 0.0)


def robot_rows(
    tallies: NDArray[np.float64], max_steps: int, duration_s: float, episode_steps: int
) -> list[dict[str, Any]]:
    """One Table 1 row per robot of one evaluation world (``tallies``: robots x EV columns);
    ``duration_s`` is its share of the world's wall time, up to its last step."""
    steps = tallies[:, EV_STEPS]
    counted = steps + 1  # rows 0..steps of the robot's own path
    reached = tallies[:, EV_REACHED] > 0
    swept = tallies[:, EV_SWEPT] > 0
    efficiency = _efficiency(tallies)
    share = steps / max(episode_steps, 1)
    return [
        {
            "robot": i,
            "reached": bool(reached[i]),
            "swept_up": bool(swept[i]),
            "total_steps": int(steps[i]) if reached[i] else max_steps,
            "steps_to_reach": int(steps[i]) if reached[i] else None,
            "final_distance": float(tallies[i, EV_FINAL_DISTANCE]),
            "average_distance": float(tallies[i, EV_SUM_DISTANCE] / counted[i]),
            "average_concentration": float(tallies[i, EV_SUM_CONCENTRATION] / counted[i]),
            "duration_s": float(duration_s * share[i]),
            "collisions": int(tallies[i, EV_COLLISIONS]),
            "path_length": float(tallies[i, EV_PATH_LENGTH]),
            "path_efficiency": float(efficiency[i]),
            "return": float(tallies[i, EV_RETURN]),
        }
        for i in range(tallies.shape[0])
    ]


def _mean(values: NDArray[np.float64]) -> float | None:
    return stats.exact_mean(values) if values.size else None


def swarm_summary(
    tallies: NDArray[np.float64], cells: NDArray[np.int64], capacity: int | None, max_steps: int
) -> dict[str, Any]:
    """The swarm's numbers in one evaluation world (``cells``: cells x CELL columns)."""
    load = cells[:, CELL_LOAD]
    out: dict[str, Any] = {
        "robots_per_cell": stats.exact_mean(load.astype(np.float64)),
        "most_robots_on_a_cell": int(load.max()),
        "bumps": int(tallies[:, EV_BUMPS].sum()),
    }
    if capacity is not None:
        treated = cells[:, CELL_TREATED_AT] >= 0
        out["cells_treated"] = int(treated.sum())
        out["treated_fraction"] = float(treated.mean())
        out["time_to_treat_all"] = (
            int(cells[:, CELL_TREATED_AT].max()) if treated.all() else int(max_steps)
        )
        out["never_delivered"] = float((tallies[:, EV_REACHED] == 0).mean())
    return out


def world_summary(
    tallies: NDArray[np.float64], max_steps: int, episode_steps: int, duration_s: float
) -> dict[str, Any]:
    """Table 1 for the swarm in one evaluation world (see the module's definitions)."""
    reached = tallies[:, EV_REACHED] > 0
    swept = tallies[:, EV_SWEPT] > 0
    steps = tallies[:, EV_STEPS]
    final = tallies[:, EV_FINAL_DISTANCE]
    counted = steps + 1
    return {
        "total_steps": float(np.median(np.where(reached, steps, max_steps))),
        "mean_steps_to_reach": _mean(steps[reached]),
        "episode_steps": int(episode_steps),
        "success_rate": float((reached & ~swept).mean()),
        "final_distance": stats.exact_mean(final),
        "final_distance_reached": _mean(final[reached]),
        "final_distance_unreached": _mean(final[~reached]),
        "average_distance": stats.exact_mean(tallies[:, EV_SUM_DISTANCE] / counted),
        "average_concentration": stats.exact_mean(tallies[:, EV_SUM_CONCENTRATION] / counted),
        "collisions": int(tallies[:, EV_COLLISIONS].sum()),
        "path_efficiency": stats.exact_mean(_efficiency(tallies)),
        "mean_return": stats.exact_mean(tallies[:, EV_RETURN]),
        "duration_s": float(duration_s),
        "robots": int(tallies.shape[0]),
        "reached": int(reached.sum()),
        "swept_up": int(swept.sum()),
    }


def over_worlds(
    worlds: Sequence[dict[str, Any]], cells: int
) -> tuple[dict[str, Any], dict[str, dict[str, Any]]]:
    """The summary (each number the mean over the worlds where it exists, counts summed) and,
    per averaged metric, its n, sd and 95% interval over the worlds, kept to its range; a share
    of trials (``SHARES_OF``; ``cells`` cells a world) pools the worlds' trials."""
    summary: dict[str, Any] = {}
    uncertainty: dict[str, dict[str, Any]] = {}
    given = tuple(key for key in SWARM if worlds and key in worlds[0])
    for key in AVERAGED + given:
        values = [float(w[key]) for w in worlds if w.get(key) is not None]
        values = [v for v in values if math.isfinite(v)]
        if key in SHARES_OF:
            each = int(worlds[0]["robots"]) if SHARES_OF[key] == "robots" else cells
            described = stats.describe_share(values, [each] * len(values))
        else:
            described = stats.describe(values, bounds=RANGES[key])
        summary[key] = described.mean
        uncertainty[key] = {
            "n": described.n,
            "sd": described.sd,
            "ci_low": described.ci_low,
            "ci_high": described.ci_high,
            "method": described.method,
        }
    summary["robots"] = int(worlds[0]["robots"]) if worlds else 0
    summary["reached"] = int(sum(w["reached"] for w in worlds))
    summary["swept_up"] = int(sum(w.get("swept_up", 0) for w in worlds))
    summary["worlds"] = len(worlds)
    return summary, uncertainty
