"""What a simulation returns: plain arrays and JSON-ready dicts.

``SimulationResult.to_dict()`` is the metrics document shared by the command line (``--json``)
and the REST API; ``arrays()`` holds everything else as named numpy arrays (for ``.npz`` files and
binary blobs). Only the timing fields (``summary.duration_s``, ``robots[*].duration_s``,
``work.engine_s``) vary between two runs of the same scenario and seed.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from nanonav.scenario import Scenario

TIMING_KEYS = frozenset({"duration_s", "engine_s"})


@dataclass(frozen=True)
class Trajectory:
    """The recorded evaluation episode.

    Row ``k`` of every per-step array is the state after step ``step[k]``: row 0 is the start,
    and rows follow every ``stride`` steps, the last row being the episode's end. The stride is
    1 unless a row for every step would overflow the history cap (``simulate``'s
    ``record_bytes``), which the per-step arrays (``step``, ``robots``, ``cells``, ``obstacles``,
    ``concentration``, ``distance``) share. A robot's path ends at the row whose step equals its
    ``robot_steps``: it stops once it reaches a cell.

    ``obstacles`` has one row per history row when obstacles move (``obstacles.motion_std`` >
    0), and a single row, ``(1, obstacles, 3)``, when they stand still: their centres for the
    whole episode. ``obstacles_at`` reads either.
    """

    step: NDArray[np.int64]  # (rows,) the step each row shows
    robots: NDArray[np.float64]  # (rows, robots, 3) positions
    cells: NDArray[np.float64]  # (rows, cells, 3) positions
    obstacles: NDArray[np.float64]  # (rows, obstacles, 3) centres; (1, obstacles, 3) if still
    concentration: NDArray[np.float64]  # (rows, robots) true concentration at each robot
    distance: NDArray[np.float64]  # (rows, robots) true distance to the nearest cell
    robot_steps: NDArray[np.int64]  # (robots,) steps each robot was active (to its reach, or T)
    reached: NDArray[np.bool_]  # (robots,) whether each robot reached a cell
    emitter_offsets: NDArray[np.float64]  # (cells, emitters, 3); the inverse-square field's
    obstacle_radius: float
    stride: int = 1
    # active Brownian physics only: each robot's unit heading (rows, robots, 3) and the reading
    # it took, with its Berg-Purcell noise (rows, robots), beside the true concentration
    headings: NDArray[np.float64] | None = None
    sensed: NDArray[np.float64] | None = None
    # the swarm: payloads each cell had received (rows, cells), the cell each robot delivered
    # to, -1 if none (robots,), and with a communication model the net signal each robot read
    # (rows, robots); None in results stored before they were recorded
    cell_loads: NDArray[np.int64] | None = None
    delivered_to: NDArray[np.int64] | None = None
    signals: NDArray[np.float64] | None = None

    @property
    def length(self) -> int:
        """Steps the episode lasted."""
        return int(self.step[-1])

    @property
    def obstacles_move(self) -> bool:
        """Whether ``obstacles`` holds a row per history row (else one row for the episode)."""
        return bool(self.obstacles.shape[0] > 1)

    def obstacles_at(self, row: int) -> NDArray[np.float64]:
        """Obstacle centres ``(obstacles, 3)`` at history row ``row`` (negative counts from the
        end), whether obstacles move or not."""
        centres: NDArray[np.float64] = self.obstacles[row if self.obstacles_move else 0]
        return centres


@dataclass(frozen=True)
class QTable:
    """The learned action values with readable labels; ``values`` is ``(states, actions)`` for a
    shared table and ``(robots, states, actions)`` when every robot learns its own."""

    states: list[str]
    actions: list[str]
    values: NDArray[np.float64]
    visits: NDArray[np.int64]

    def to_dict(self) -> dict[str, Any]:
        return {
            "states": self.states,
            "actions": self.actions,
            "values": self.values.tolist(),
            "visits": self.visits.tolist(),
        }


@dataclass(frozen=True)
class SimulationResult:
    """Everything one run produced.

    ``summary`` is Table 1 for the swarm, each number the mean over the evaluation worlds
    (``metrics`` says what each means); ``uncertainty`` gives, per number, n, sd and the 95%
    interval over those worlds, kept to the number's range (its ``method`` says how);
    ``worlds`` holds every world's own summary;
    ``robots`` and ``trajectory`` are the first evaluation world's. ``completed`` is false when
    the caller stopped the run early: the episodes finished so far are kept, and there is no
    evaluation (``trajectory`` is None, the summaries empty).
    """

    scenario: Scenario
    summary: dict[str, Any]
    robots: list[dict[str, Any]]
    episodes: list[dict[str, Any]]
    work: dict[str, Any]
    trajectory: Trajectory | None
    qtable: QTable | None
    completed: bool = True
    uncertainty: dict[str, dict[str, Any]] = field(default_factory=dict)
    worlds: list[dict[str, Any]] = field(default_factory=list)
    # the active Brownian physics' derived numbers (diffusion, persistence length, Peclet
    # numbers, times in s); empty in the lattice physics
    physics: dict[str, float] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        """The metrics document: scenario, Table 1 summary and its uncertainty over the
        evaluation worlds, each world's summary, per-robot rows, learning curve, work."""
        return {
            "scenario": self.scenario.model_dump(mode="json"),
            "completed": self.completed,
            "summary": self.summary,
            "uncertainty": self.uncertainty,
            "worlds": self.worlds,
            "robots": self.robots,
            "episodes": self.episodes,
            "work": self.work,
            **({"physics": self.physics} if self.physics else {}),
        }

    @classmethod
    def from_stored(
        cls, document: dict[str, Any], arrays: dict[str, NDArray[Any]]
    ) -> SimulationResult:
        """The result again, from its metrics document (``to_dict``) and its trajectory arrays
        (``arrays``), as a store keeps them: enough to draw its pictures later. The Q-table is
        not needed for that and is left out."""
        trajectory = None
        if "step" in arrays:
            step = arrays["step"]
            trajectory = Trajectory(
                step=step,
                robots=arrays["robots"],
                cells=arrays["cells"],
                obstacles=arrays["obstacles"],
                concentration=arrays["concentration"],
                distance=arrays["distance"],
                # stored by older versions as "steps"
                robot_steps=arrays["robot_steps"] if "robot_steps" in arrays else arrays["steps"],
                reached=arrays["reached"],
                emitter_offsets=arrays["emitter_offsets"],
                obstacle_radius=float(arrays["obstacle_radius"]),
                stride=int(step[1] - step[0]) if step.shape[0] > 1 else 1,
                headings=arrays.get("headings"),
                sensed=arrays.get("sensed"),
                cell_loads=arrays.get("cell_loads"),
                delivered_to=arrays.get("delivered_to"),
                signals=arrays.get("signals"),
            )
        return cls(
            scenario=Scenario.model_validate(document["scenario"]),
            summary=document.get("summary") or {},
            robots=document.get("robots") or [],
            episodes=document.get("episodes") or [],
            work=document.get("work") or {},
            trajectory=trajectory,
            qtable=None,
            completed=bool(document.get("completed", True)),
            uncertainty=document.get("uncertainty") or {},
            worlds=document.get("worlds") or [],
            physics=document.get("physics") or {},
        )

    def arrays(self) -> dict[str, NDArray[Any]]:
        """The trajectory and Q-table as named arrays, for ``numpy.savez`` and binary storage
        (``obstacles`` keeps its shape: one row when obstacles stand still)."""
        out: dict[str, NDArray[Any]] = {}
        if self.trajectory is not None:
            t = self.trajectory
            out.update(
                step=t.step,
                robots=t.robots,
                cells=t.cells,
                obstacles=t.obstacles,
                concentration=t.concentration,
                distance=t.distance,
                robot_steps=t.robot_steps,
                reached=t.reached,
                emitter_offsets=t.emitter_offsets,
                obstacle_radius=np.array(t.obstacle_radius),
            )
            if t.headings is not None and t.sensed is not None:
                out.update(headings=t.headings, sensed=t.sensed)
            for name in ("cell_loads", "delivered_to", "signals"):
                value = getattr(t, name)
                if value is not None:
                    out[name] = value
        if self.qtable is not None:
            out.update(q_values=self.qtable.values, q_visits=self.qtable.visits)
        return out


def without_timings(document: Any) -> Any:
    """``document`` with every timing field removed, for comparing runs bit for bit."""
    if isinstance(document, dict):
        return {k: without_timings(v) for k, v in document.items() if k not in TIMING_KEYS}
    if isinstance(document, list):
        return [without_timings(v) for v in document]
    return document
