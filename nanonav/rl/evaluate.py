"""A policy from outside the engine (a trained network, say) evaluated as a job evaluates a
learned table: the scenario's evaluation worlds, measured and the first recorded, into the same
``SimulationResult`` that ``simulate`` returns.

The worlds are those ``simulate`` evaluates in for the scenario's seed (drawn one after another
from its evaluation stream), so a network and a rule evaluated with one seed meet the same
worlds and pair by seed; the first world also runs on ``simulate``'s dynamics stream, the
others each on one of their own. The worlds step together, in rounds of at most
``ROUND_ROBOTS`` robots (which change nothing but the memory taken): one call of ``decide`` a
decision takes the observations of every robot of every world of the round (one row each;
under the sequential schedule, of the robot whose turn it is in each world).

A ``decide`` with a memory (``remembers`` true: a recurrent network) is evaluated only where
every robot decides at once, so that row k is the same robot call after call; its ``forget()``
is called as each round begins.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

import numpy as np
from numpy.typing import NDArray

from nanonav.engine import metrics, phases, state
from nanonav.engine.kernel import tally_evaluation
from nanonav.engine.observations import observation_of
from nanonav.engine.result import SimulationResult
from nanonav.engine.simulation import (
    DEFAULT_RECORD_BYTES,
    Progress,
    ProgressCallback,
    derived_physics,
    evaluated_worlds,
    recorded_trajectory,
)
from nanonav.engine.state import Social, Swarm, Treatment
from nanonav.engine.world import DYNAMICS_STREAM, EVALUATION_STREAM, stream
from nanonav.engine.worlds import Worlds
from nanonav.rl.stops import PolicyFailed, Stopped
from nanonav.scenario import Scenario, ScenarioError, Steering
from nanonav.scenario.work import REMEMBERS_AT_ONCE, ROUND_ROBOTS, decides_at_once

# (rows, observation width) float64 in the scenario's units -> (rows,) action numbers, or
# steering continuously (rows, 2) turns
Decide = Callable[[NDArray[np.float64]], NDArray[Any]]
# Seconds of work between progress reports
PROGRESS_EVERY_S = 0.1


def _views(batch: phases.Sim, k: int) -> tuple[Swarm, Social, Treatment]:
    """World ``k`` of a batch's swarm, social and treatment arrays."""
    return (
        Swarm(*(a[k] for a in batch.s)),
        Social(*(a[k] for a in batch.so)),
        Treatment(*(a[k] for a in batch.tr)),
    )


# long: the evaluation's rounds of worlds, in the order simulate's evaluation draws them
def evaluate(
    scenario: Scenario,
    decide: Decide,
    progress: ProgressCallback | None = None,
    *,
    record_bytes: int = DEFAULT_RECORD_BYTES,
    steering: Steering = "discrete",
) -> SimulationResult:
    """Evaluate ``decide`` in ``scenario``'s ``evaluation.worlds`` worlds (it trains nothing:
    ``learning.episodes`` must be 0). ``decide`` gets the observations (``observation_of``'s
    columns, as ``NanoNavEnv`` gives them) and returns an action of the scenario's action set
    for each row (``steering`` continuously: a turn, side and up, as ``NanoNavEnv`` takes
    it); each is held for the decision interval, as in the environments. Raises
    ``PolicyFailed`` when it raises or answers anything else. ``progress`` is called about
    every 0.1 s; False stops the run (``completed`` False)."""
    if scenario.learning.episodes:
        raise ScenarioError(
            "learning.episodes", "a policy from outside is evaluated, not trained: it must be 0"
        )
    if getattr(decide, "remembers", False) and not decides_at_once(scenario):
        raise PolicyFailed(REMEMBERS_AT_ONCE)
    count = scenario.evaluation.worlds
    robots = scenario.robots.count
    tallies = np.zeros((count, robots, state.EV_COLUMNS))
    cells = np.zeros((count, scenario.cells.count, state.CELL_COLUMNS), dtype=np.int64)
    steps = np.zeros(count, dtype=np.int64)
    robot_steps = np.zeros(count)
    # one evaluation stream draws every world in turn, as simulate's evaluation draws them
    drawn = stream(scenario.seed, EVALUATION_STREAM)
    run = _Round(scenario, decide, progress, count, steering)
    per_round = max(1, ROUND_ROBOTS // robots)
    first = Worlds(scenario, 1, scenario.robots.schedule, measure=phases.RECORDED,
                   record_bytes=record_bytes, steering=steering)  # fmt: skip
    trajectory = None
    for start in range(0, count, per_round):
        size = min(per_round, count - start)
        batches = [first] if start == 0 else []
        rest = size - len(batches)
        if rest:
            batches.append(
                Worlds(
                    scenario,
                    rest,
                    scenario.robots.schedule,
                    measure=phases.MEASURED,
                    steering=steering,
                )
            )
        k = start
        for b in batches:
            for j in range(b.count):
                # the first world on simulate's own dynamics stream, each other on its own
                b.use_generators(
                    j, drawn, stream(scenario.seed, DYNAMICS_STREAM, *((k,) if k else ()))
                )
                k += 1
        if not run.through(batches):
            work = {"robot_steps": run.robot_steps, "engine_s": run.seconds,
                    "decide_calls": run.calls}  # fmt: skip
            return SimulationResult(scenario, {}, [], [], work, None, None, completed=False)
        world = start
        for b in batches:
            for j in range(b.count):
                swarm, social, treatment = _views(b.batch, j)
                tally_evaluation(swarm, social, treatment, tallies[world], cells[world])
                steps[world] = b.steps(j)
                robot_steps[world] = float(swarm.steps.sum())
                world += 1
        if start == 0:
            trajectory = recorded_trajectory(
                scenario, _recording(first), tallies[0], int(steps[0]), first.params.record_stride
            )
        run.done += size
    engine_s = run.seconds
    worlds, rows_of_first = evaluated_worlds(scenario, tallies, cells, steps, robot_steps, engine_s)
    summary, uncertainty = metrics.over_worlds(worlds, scenario.cells.count)
    # decide_calls: what marks a result decided from outside (a network's, say)
    work = {"robot_steps": int(robot_steps.sum()), "engine_s": engine_s, "decide_calls": run.calls}
    return SimulationResult(
        scenario, summary, rows_of_first, [], work, trajectory, None,
        uncertainty=uncertainty, worlds=worlds, physics=derived_physics(scenario, summary),
    )  # fmt: skip


def _decided(decide: Decide, rows: NDArray[np.float64], worlds: Worlds) -> NDArray[Any]:
    """``decide``'s action for each row, checked: one integer of the action set a row, or
    steering continuously a turn of two finite numbers."""
    try:
        chosen = np.asarray(decide(rows))
    except Stopped:
        raise
    except Exception as error:
        raise PolicyFailed(f"the policy raised {type(error).__name__}: {error}") from error
    if worlds.continuous:
        if chosen.shape != (rows.shape[0], 2):
            raise PolicyFailed(
                f"the policy answered an array of shape {chosen.shape} for {rows.shape[0]} "
                "observations, not a turn (side, up) each"
            )
        if not worlds.in_action_set(chosen):
            raise PolicyFailed("the policy answered turns that are not all finite numbers")
        return chosen.astype(np.float64, copy=False)
    actions = worlds.actions
    if chosen.shape != (rows.shape[0],):
        raise PolicyFailed(
            f"the policy answered an array of shape {chosen.shape} for {rows.shape[0]} "
            "observations, not one action each"
        )
    if chosen.dtype.kind not in "iu":
        raise PolicyFailed(f"the policy answered actions of {chosen.dtype}, not integers")
    if chosen.size and (chosen.min() < 0 or chosen.max() >= actions):
        bad = chosen[(chosen < 0) | (chosen >= actions)][0]
        raise PolicyFailed(f"the policy answered action {bad}, not one of 0..{actions - 1}")
    return chosen.astype(np.int64, copy=False)


class _Round:
    """Rounds of worlds stepped together to their ends, ``decide`` deciding for every robot of
    every world of a round in one call a decision; the work done and the progress reported
    over all of them."""

    def __init__(
        self, scenario: Scenario, decide: Decide, progress: ProgressCallback | None, count: int,
        steering: Steering,
    ) -> None:  # fmt: skip
        self.scenario = scenario
        self.decide = decide
        self.progress = progress
        self.count = count
        self.columns = observation_of(scenario, steering).columns
        self.robots = scenario.robots.count
        self.sequential = not decides_at_once(scenario)
        self.calls = 0
        self.done = 0  # worlds of earlier rounds
        self.seconds = 0.0
        self.robot_steps = 0
        self.last_report = time.perf_counter()

    def through(self, batches: list[Worlds]) -> bool:
        """Step ``batches`` until every world is over; False if ``progress`` said stop."""
        started = time.perf_counter()
        try:
            return self._through(batches)
        except Stopped:
            return False
        finally:
            self.seconds += time.perf_counter() - started
            self.robot_steps += sum(int(b.batch.s.steps.sum()) for b in batches)

    def _through(self, batches: list[Worlds]) -> bool:
        robots = self.robots
        forget = getattr(self.decide, "forget", None)
        if forget is not None:
            forget()  # a recurrent policy's robots start their episodes afresh
        # who decides, as (worlds, robots) index pairs: every robot, or the one whose turn it is
        everyone = [
            (np.repeat(np.arange(b.count), robots), np.tile(np.arange(robots), b.count))
            for b in batches
        ]
        actions = [b.blank_actions() for b in batches]
        none_fresh = [np.zeros(b.count, dtype=np.bool_) for b in batches]
        for b in batches:
            b.step(None, np.ones(b.count, dtype=np.bool_))
        while not all(b.over.all() for b in batches):
            picks = [
                (np.arange(b.count), b.batch.pc.clock[:, phases.CLOCK_NEXT].clip(0))
                if self.sequential
                else pairs
                for b, pairs in zip(batches, everyone, strict=True)
            ]
            rows = np.concatenate(
                [b.obs[w, r][:, self.columns] for b, (w, r) in zip(batches, picks, strict=True)]
            )
            chosen = _decided(self.decide, rows, batches[0])
            self.calls += 1
            at = 0
            for b, (w, r), given, fresh in zip(batches, picks, actions, none_fresh, strict=True):
                given[w, r] = chosen[at : at + w.size]
                at += w.size
                b.step(given, fresh, checked=True)
            if not self._report(batches):
                return False
        return True

    def _report(self, batches: list[Worlds]) -> bool:
        """Report progress about every ``PROGRESS_EVERY_S``; False if told to stop."""
        now = time.perf_counter()
        if self.progress is None or now - self.last_report < PROGRESS_EVERY_S:
            return True
        self.last_report = now
        done = self.done + sum(int(b.over.sum()) for b in batches)
        step = min(b.steps(k) for b in batches for k in range(b.count))
        where = Progress(done, self.count, step, self.scenario.learning.max_steps)
        return self.progress(where) is not False


def _recording(worlds: Worlds) -> state.Recording:
    """The history of the first world of ``worlds``."""
    return state.Recording(*(a[0] for a in worlds.batch.rec))
