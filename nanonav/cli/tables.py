"""What the command prints as text: Table 1 of a run. Pure functions of plain data."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

MAX_ROBOT_ROWS = 20


def text_table(
    columns: Sequence[str], rows: Sequence[Sequence[str]], *, align_right: Sequence[bool]
) -> list[str]:
    """Columns padded to their widest cell, under a rule of dashes."""
    widths = [max(len(c), *(len(r[i]) for r in rows)) for i, c in enumerate(columns)]

    def line(cells: Sequence[str]) -> str:
        return "  ".join(
            cell.rjust(w) if right else cell.ljust(w)
            for cell, w, right in zip(cells, widths, align_right, strict=True)
        ).rstrip()

    rule = "  ".join("-" * w for w in widths)
    return [line(columns), rule, *(line(r) for r in rows)]


# ---------------------------------------------------------------- Table 1


def _number(value: Any, digits: int = 2, suffix: str = "") -> str:
    if value is None:
        return "n/a"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, int):
        return f"{value}{suffix}"
    return f"{float(value):.{digits}f}{suffix}"


def _seconds(value: Any) -> str:
    if value is None:
        return "n/a"
    seconds = float(value)
    return f"{seconds:.2f} seconds" if seconds >= 1 else f"{seconds:.3g} seconds"


def _percent(value: Any) -> str:
    return "n/a" if value is None else f"{100 * float(value):.1f}%"


def _plural(count: int, word: str) -> str:
    return f"{count} {word}{'s' if count != 1 else ''}"


def format_table(document: Mapping[str, Any]) -> str:
    """Table 1 of the paper as text, from a run's metrics document (``SimulationResult.to_dict``
    or ``GET /jobs/{id}/metrics``), with success rate, collisions and path efficiency, and for a
    swarm a per-robot table (the first ``MAX_ROBOT_ROWS`` robots)."""
    scenario = document["scenario"]
    summary = document.get("summary") or {}
    robots_rows = document.get("robots") or []
    rows = [
        ("Total Steps", _number(summary.get("total_steps"))),
        ("Final Distance", _number(summary.get("final_distance"))),
        ("Average Distance", _number(summary.get("average_distance"))),
        ("Average Biomarker Concentration", _number(summary.get("average_concentration"))),
        ("Simulation Duration", _seconds(summary.get("duration_s"))),
        ("Success Rate", _percent(summary.get("success_rate"))),
        ("Collisions", _number(summary.get("collisions"))),
        ("Path Efficiency", _number(summary.get("path_efficiency"))),
    ]
    robots = int(scenario["robots"]["count"])
    header = (
        f"Table 1: {scenario.get('preset') or 'custom scenario'}, seed {scenario['seed']}, "
        f"{_plural(robots, 'robot')}, {_plural(int(scenario['cells']['count']), 'cell')}, "
        f"{scenario['robots']['policy']}, "
        f"{scenario['learning']['episodes']} training episodes + evaluation"
    )
    lines = [header, *text_table(("Parameter", "Result"), rows, align_right=(False, True))]
    if robots > 1 and robots_rows:
        lines += ["", "Per robot (evaluation episode):"]
        shown = robots_rows[:MAX_ROBOT_ROWS]
        robot_rows = [
            (
                str(row.get("robot")),
                _number(row.get("reached")),
                _number(row.get("total_steps")),
                _number(row.get("final_distance")),
                _number(row.get("average_distance")),
                _number(row.get("average_concentration")),
                _number(row.get("collisions")),
                _number(row.get("path_efficiency")),
            )
            for row in shown
        ]
        columns = ("robot", "reached", "steps", "final dist", "avg dist", "avg conc",
                   "collisions", "path eff")  # fmt: skip
        lines += text_table(columns, robot_rows, align_right=(True,) * len(columns))
        if len(robots_rows) > len(shown):
            lines.append(
                f"... and {len(robots_rows) - len(shown)} more robots (see --json or metrics.json)"
            )
    return "\n".join(lines)
