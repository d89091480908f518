"""The paper's Table 1 as rows of text, from a run's metrics document: the one layout the
command line and the dashboard both show."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any


def number(value: Any, digits: int = 2, suffix: str = "") -> str:
    if value is None:
        return "n/a"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, int):
        return f"{value}{suffix}"
    return f"{float(value):.{digits}f}{suffix}"


def seconds(value: Any) -> str:
    if value is None:
        return "n/a"
    given = float(value)
    return f"{given:.2f} seconds" if given >= 1 else f"{given:.3g} seconds"


def percent(value: Any) -> str:
    return "n/a" if value is None else f"{100 * float(value):.1f}%"


METRICS: tuple[tuple[str, str, Callable[[Any], str]], ...] = (
    ("Total Steps", "total_steps", number),
    ("Final Distance", "final_distance", number),
    ("Average Distance", "average_distance", number),
    ("Average Biomarker Concentration", "average_concentration", number),
    # the wall-clock time the machine took, not simulated time
    ("Computing Time per World", "duration_s", seconds),
    ("Success Rate", "success_rate", percent),
    ("Collisions", "collisions", number),
    ("Path Efficiency", "path_efficiency", number),
)


# The swarm's numbers, after Table 1, for runs that have them (nanonav.engine.metrics.SWARM)
SWARM: tuple[tuple[str, str, Callable[[Any], str]], ...] = (
    ("Cells Treated", "cells_treated", number),
    ("Share of Cells Treated", "treated_fraction", percent),
    ("Steps to Treat Every Cell", "time_to_treat_all", number),
    ("Payloads per Cell", "robots_per_cell", number),
    ("Most Payloads on a Cell", "most_robots_on_a_cell", number),
    ("Robots That Delivered Nothing", "never_delivered", percent),
    ("Bumps Between Robots", "bumps", number),
)


def significant(value: Any) -> str:
    """Three significant figures: physical concentrations span decades below 1 nM."""
    return "n/a" if value is None else f"{float(value):.3g}"


def nanomolar(value: Any) -> str:
    """A concentration in nM to three significant figures, with its unit: ``2.3e-05 nM``, never
    a bare ``0.00``."""
    return "n/a" if value is None else f"{significant(value)} nM"


def micrometres(value: Any) -> str:
    """A length in µm, to two decimals, with its unit."""
    return number(value, suffix=" µm")


# In the lattice: its lengths and the field's concentration have no physical unit, and say so
LATTICE_LABELS: dict[str, str] = {
    "final_distance": "Final Distance (length units)",
    "average_distance": "Average Distance (length units)",
    "average_concentration": "Average Biomarker Concentration (a.u.)",
}

# In the active Brownian physics: the same metrics with their units
PHYSICAL: dict[str, tuple[str, Callable[[Any], str]]] = {
    "final_distance": ("Final Distance", micrometres),
    "average_distance": ("Average Distance", micrometres),
    "average_concentration": ("Average Biomarker Concentration", nanomolar),
}


def rows(document: Mapping[str, Any]) -> list[tuple[str, str, str]]:
    """(parameter, result, 95% interval over the evaluation worlds) for each Table 1 metric;
    the interval is empty when there is none (one world, or a metric without spread). In the
    active Brownian physics lengths are given in µm and concentrations in nM (each value with
    its unit), and steps with how long one lasts; in the lattice the labels say that lengths are
    in its length units and concentrations arbitrary. The computing time is the machine's."""
    summary = document.get("summary") or {}
    uncertainty = document.get("uncertainty") or {}
    physics = (document.get("scenario") or {}).get("physics") or {}
    physical = physics.get("model") == "active_brownian"
    found = []
    for label, key, show in METRICS:
        if physical and key in PHYSICAL:
            label, show = PHYSICAL[key]
        elif not physical:
            label = LATTICE_LABELS.get(key, label)
        if physical and key == "total_steps" and physics.get("dt_s"):
            label = f"Total Steps (of {physics['dt_s']:g} s)"
        spread = uncertainty.get(key) or {}
        low, high = spread.get("ci_low"), spread.get("ci_high")
        interval = "" if low is None or high is None else f"[{show(low)}, {show(high)}]"
        found.append((label, show(summary.get(key)), interval))
    for label, key, show in SWARM:
        if key not in summary:
            continue
        spread = uncertainty.get(key) or {}
        low, high = spread.get("ci_low"), spread.get("ci_high")
        interval = "" if low is None or high is None else f"[{show(low)}, {show(high)}]"
        found.append((label, show(summary[key]), interval))
    return found
