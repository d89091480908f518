"""Table 1 of the paper, for the swarm and per robot, from the evaluation episode's tallies."""

from __future__ import annotations

from typing import Any

import numpy as np

from nanonav.engine.state import Swarm


def robot_rows(swarm: Swarm, duration_s: float, episode_steps: int) -> list[dict[str, Any]]:
    """One Table 1 row per robot; ``duration_s`` is its share of the episode's wall time, up to
    its last step."""
    counted = swarm.steps + 1  # rows 0..steps of the robot's own path
    average_distance = swarm.sum_dist / counted
    average_concentration = swarm.sum_conc / counted
    straight = np.linalg.norm(swarm.pos - swarm.start, axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        efficiency = np.where(swarm.path_length > 0, straight / swarm.path_length, 0.0)
    share = swarm.steps / max(episode_steps, 1)
    return [
        {
            "robot": i,
            "reached": bool(not swarm.active[i]),
            "total_steps": int(swarm.steps[i]),
            "final_distance": float(swarm.last_dist[i]),
            "average_distance": float(average_distance[i]),
            "average_concentration": float(average_concentration[i]),
            "duration_s": float(duration_s * share[i]),
            "collisions": int(swarm.collisions[i]),
            "path_length": float(swarm.path_length[i]),
            "path_efficiency": float(efficiency[i]),
            "return": float(swarm.returns[i]),
        }
        for i in range(swarm.pos.shape[0])
    ]


def swarm_summary(
    rows: list[dict[str, Any]], episode_steps: int, duration_s: float
) -> dict[str, Any]:
    """Table 1 for the whole swarm: the episode's length, means over robots, and totals."""
    reached = [r for r in rows if r["reached"]]

    def mean(key: str, of: list[dict[str, Any]] = rows) -> float | None:
        return float(np.mean([r[key] for r in of])) if of else None

    return {
        "total_steps": int(episode_steps),
        "final_distance": mean("final_distance"),
        "average_distance": mean("average_distance"),
        "average_concentration": mean("average_concentration"),
        "duration_s": float(duration_s),
        "success_rate": len(reached) / len(rows),
        "collisions": int(sum(r["collisions"] for r in rows)),
        "path_efficiency": mean("path_efficiency"),
        "mean_steps_to_reach": mean("total_steps", reached),
        "mean_return": mean("return"),
        "robots": len(rows),
        "reached": len(reached),
    }
