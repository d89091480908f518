"""Run one claimed job: simulate with progress, cancel and time checks, then store the result.

Pictures are not drawn here: the API draws each one the first time it is asked for, so a job
costs what its simulation costs."""

from __future__ import annotations

import contextlib
import dataclasses
import enum
import logging
import math
import threading
import time
from collections.abc import Callable, Iterator
from typing import TYPE_CHECKING, Any, TypeVar

import numpy as np
from numpy.typing import NDArray
from pydantic import ValidationError
from sqlalchemy.exc import SQLAlchemyError

from nanonav.engine import Progress, SimulationResult, simulate
from nanonav.finite import finite
from nanonav.policy import (
    Network,
    UnusablePolicy,
    learned_policy,
    network_layout,
    steering_of,
)
from nanonav.rl.evaluate import evaluate
from nanonav.rl.graph import InvalidModel
from nanonav.rl.onnx_policy import Limits, NetworkPolicy
from nanonav.rl.stops import PolicyFailed, Stopped
from nanonav.scenario import Scenario
from nanonav.scenario.work import training_work
from nanonav.settings import Settings
from nanonav.store import Claim, JobRecord, JobStore, LeaseLost, Outcome
from nanonav.store.faults import is_permanent, is_transient, reason
from nanonav.store.policies import Network as StoredNetwork
from nanonav.studies.report import learning_curve, study_metrics

if TYPE_CHECKING:  # the trainer needs torch, which only a worker that trains has
    from nanonav.rl.job import Trained

logger = logging.getLogger(__name__)

TRAJECTORY_KEYS = (
    "step",
    "robots",
    "cells",
    "obstacles",
    "concentration",
    "distance",
    "headings",  # the active Brownian physics only
    "sensed",
    "cell_loads",  # the swarm
    "delivered_to",
    "signals",  # with a communication model only
    "robot_steps",
    "reached",
    "emitter_offsets",
    "obstacle_radius",
)


class Stop(enum.Enum):
    """Why a run was stopped before its end."""

    CANCELLED = "cancelled"  # a client asked
    TIME_LIMIT = "time limit"  # it ran longer than the settings allow
    SHUTDOWN = "shutdown"  # the worker was told to stop: the job goes back to the queue
    LEASE_LOST = "lease lost"  # another worker owns the job now: write nothing


class Watch:
    """The progress callback: writes progress at most every ``progress_interval_s`` and decides,
    from the answer, the clock and the shutdown flag, whether the run goes on."""

    def __init__(
        self,
        store: JobStore,
        claim: Claim,
        settings: Settings,
        shutdown: threading.Event,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.store = store
        self.claim = claim
        self.settings = settings
        self.shutdown = shutdown
        self.clock = clock
        self.started = clock()
        self.last_write = -math.inf
        self.stop: Stop | None = None
        self.progress = Progress(0, 1, 0, 1)
        # a network's training: the decisions done (None: the job trains none), and the
        # share of the job's work before its evaluation, which then fills the rest
        self.decisions: int | None = None
        # and its training curve, written with the progress when it has grown
        self.curve: list[dict[str, Any]] | None = None
        self._curve_written: list[dict[str, Any]] | None = None
        self.before = 0.0
        self.share = 1.0

    def poll(self) -> bool:
        """Whether the run goes on, asked while a network decides (between progress reports):
        the same checks, with the last progress reported."""
        return self(self.progress)

    def __call__(self, progress: Progress) -> bool:
        self.progress = progress
        now = self.clock()
        if self.shutdown.is_set():
            self.stop = Stop.SHUTDOWN
        elif now - self.started > self.settings.job_time_limit_s:
            self.stop = Stop.TIME_LIMIT
        elif now - self.last_write >= self.settings.progress_interval_s:
            self.last_write = now
            curve = self.curve if self.curve is not self._curve_written else None
            try:
                if self.store.report_progress(
                    self.claim,
                    episode=progress.episode,
                    episodes=progress.episodes,
                    fraction=self.before + self.share * progress.fraction,
                    lease_s=self.settings.lease_s,
                    decisions=self.decisions,
                    curve=curve,
                ):
                    self.stop = Stop.CANCELLED
                self._curve_written = self.curve
            except LeaseLost:
                self.stop = Stop.LEASE_LOST
            except SQLAlchemyError as error:
                if not is_transient(error):
                    raise
                # the store is busy or away for a moment: the run goes on, and the next
                # write (or the heartbeat) brings the progress and the lease up to date
                logger.warning(
                    "job %d: progress not written (%s); the run goes on",
                    self.claim.job.id, reason(error),
                )  # fmt: skip
        return self.stop is None


def run_job(
    store: JobStore, claim: Claim, settings: Settings, shutdown: threading.Event
) -> JobRecord | None:
    """Run the claimed job to its end state; None if the job went back to the queue or to
    another worker."""
    job_id = claim.job.id
    try:
        scenario = Scenario.model_validate(claim.job.scenario)
    except ValidationError as error:
        return store.fail(claim, f"the stored scenario is no longer valid: {error}")
    watch = Watch(store, claim, settings, shutdown)
    started = time.perf_counter()
    trained: Trained | None = None
    try:
        with heartbeat(store, claim, settings):
            if scenario.trains:
                result, trained = _train_and_evaluate(scenario, store, claim, settings, watch)
            else:
                result = _run(scenario, store, settings, watch)
    except (UnusablePolicy, InvalidModel) as error:
        return _fail(store, claim, f"policy_from: {error}")
    except PolicyFailed as error:
        return _fail(store, claim, f"policy_from: {error}")
    except SQLAlchemyError as error:
        logger.error("job %d: the store refused its progress: %s", job_id, reason(error))
        return _fail(store, claim, f"the store refused the job's progress: {reason(error)}")
    except Exception as error:
        logger.exception("job %d failed", job_id)
        return _fail(store, claim, f"the simulation failed: {type(error).__name__}: {error}")
    if watch.stop is Stop.LEASE_LOST:
        logger.warning("job %d: lease lost; its result is dropped", job_id)
        return None
    if watch.stop is Stop.TIME_LIMIT and not result.completed:
        limit = settings.job_time_limit_s
        return _fail(store, claim, f"stopped: the job ran past its time limit of {limit:g} s")
    if watch.stop is Stop.SHUTDOWN and not result.completed:
        logger.info("job %d: given back to the queue on shutdown", job_id)
        with contextlib.suppress(LeaseLost):
            store.release(claim)
        return None
    stored = time.perf_counter()
    try:
        with heartbeat(store, claim, settings):
            record = retrying(
                lambda: store.finish(claim, outcome(result, trained, job_id)), settings
            )
    except LeaseLost:
        logger.warning("job %d: lease lost before its result was stored", job_id)
        return None
    except SQLAlchemyError as error:
        if is_permanent(error):
            return _fail(store, claim, f"its result could not be stored: {reason(error)}")
        logger.error("job %d: the store stayed away (%s); the job will run again once its "
                     "lease runs out", job_id, reason(error))  # fmt: skip
        return None
    logger.info(
        "job %d: simulated in %.3f s, stored in %.3f s",
        job_id,
        stored - started,
        time.perf_counter() - stored,
    )
    return record


def _run(scenario: Scenario, store: JobStore, settings: Settings, watch: Watch) -> SimulationResult:
    """Simulate the scenario, or evaluate the table or network its ``policy_from`` names (as
    the store holds it now, a job's or a policy's: either may have been deleted since it was
    checked at submit, and the job fails, saying which is gone). A network is checked again
    and loaded in its own process, asking ``watch`` while it decides, and ended with the run."""
    if scenario.policy_from is None:
        return simulate(scenario, watch)
    policy = learned_policy(scenario, store.qtable)
    if not isinstance(policy, Network):
        return simulate(scenario, watch, policy=policy)
    try:
        network = NetworkPolicy(
            policy.model,
            len(policy.observation),
            len(policy.actions),
            max_bytes=settings.policy_model_max_bytes,
            continuous=steering_of(policy.actions) == "continuous",
            limits=Limits.of(settings),
            keep_going=watch.poll,
        )
    except Stopped:  # told to stop while it was checked
        return _stopped(scenario)
    with network:
        return evaluate(scenario, network, watch, steering=network.steering)


def _stopped(scenario: Scenario) -> SimulationResult:
    """The result of a run told to stop before it had anything to keep."""
    return SimulationResult(scenario, {}, [], [], {}, None, None, completed=False)


def _train_and_evaluate(
    scenario: Scenario, store: JobStore, claim: Claim, settings: Settings, watch: Watch
) -> tuple[SimulationResult, Trained | None]:
    """Train the network the scenario asks for (from the job's last checkpoint, if a worker
    before this one kept one), keeping a checkpoint in the store every
    ``learning.checkpoint_decisions``; then evaluate it on the job's evaluation worlds as a
    network given by ``policy_from`` is, checked and run in its own process. Stopped (a
    cancel, the time limit, a shutdown, a lost lease), the result is not completed and no
    network is kept."""
    from nanonav.rl.job import Checkpoint, train_network
    from nanonav.rl.training import TrainingStopped

    job_id, token = claim.job.id, claim.token
    kept = store.training.last(job_id)
    resume = None if kept is None else Checkpoint(kept.decisions, kept.data, kept.curve)
    if resume is not None:
        store.training.resumed(job_id, token, resume.decisions, resume.curve)
        logger.info("job %d: training resumed from %d decisions", job_id, resume.decisions)
    goal = scenario.training_decisions
    watch.share = training_work(scenario) / max(scenario.work, 1)
    watch.decisions = 0 if resume is None else resume.decisions

    def keep_going(decisions: int) -> bool:
        watch.decisions = decisions
        return watch(Progress(0, 1, decisions, goal))

    def grew(rows: list[dict[str, Any]]) -> None:
        watch.curve = finite(rows)

    def keep(checkpoint: Checkpoint) -> None:
        try:
            retrying(lambda: store.training.keep(
                job_id, token, decisions=checkpoint.decisions, data=checkpoint.data,
                curve=checkpoint.curve,
            ), settings)  # fmt: skip
        except LeaseLost:
            watch.stop = Stop.LEASE_LOST
            raise TrainingStopped from None

    trained = train_network(
        scenario, keep_going=keep_going, keep=keep, resume=resume,
        threads=settings.training_threads, device=settings.training_device, grew=grew,
    )  # fmt: skip
    if trained is None:
        return _stopped(scenario), None
    watch.before, watch.share = watch.share, 1.0 - watch.share
    try:
        network = NetworkPolicy(
            trained.model, len(trained.observation), len(trained.actions),
            max_bytes=settings.policy_model_max_bytes, limits=Limits.of(settings),
            keep_going=watch.poll,
        )  # fmt: skip
    except Stopped:
        return _stopped(scenario), None
    with network:
        result = evaluate(scenario.network_scenario(), network, watch, steering=network.steering)
    return dataclasses.replace(result, scenario=scenario), trained


def outcome(
    result: SimulationResult, trained: Trained | None = None, job_id: int | None = None
) -> Outcome:
    """What the store keeps of a run: metrics as JSON, trajectory and Q-table as arrays; of a
    network the job trained, its training curve and figures in the metrics, and the network
    itself, to keep as a policy of the job's owner."""
    arrays = result.arrays()
    trajectory = {k: arrays[k] for k in TRAJECTORY_KEYS if k in arrays}
    qtable: dict[str, NDArray[Any]] | None = None
    if result.qtable is not None:
        qtable = {
            "states": np.array(result.qtable.states, dtype=np.str_),
            "actions": np.array(result.qtable.actions, dtype=np.str_),
            "values": result.qtable.values,
            "visits": result.qtable.visits,
        }
    metrics = finite(result.to_dict())
    network: StoredNetwork | None = None
    if trained is not None:
        metrics["training_curve"] = finite(trained.curve)
        metrics["training"] = finite(trained.summary())
        layout = network_layout(trained.observation, trained.actions)
        network = StoredNetwork(
            layout.actions, layout.communication, trained.observation, trained.actions,
            trained.model, trained.memory, name=f"{result.scenario.robots.policy} of job {job_id}",
        )  # fmt: skip
    return Outcome(
        completed=result.completed,
        metrics=metrics,
        trajectory=trajectory or None,
        qtable=qtable,
        study_metrics=study_metrics(metrics) if result.completed else None,
        curve=learning_curve(metrics) if result.completed else None,
        trained=network if result.completed else None,
    )


def _fail(store: JobStore, claim: Claim, error: str) -> JobRecord | None:
    try:
        return retrying(lambda: store.fail(claim, error), None)
    except LeaseLost:
        return None
    except SQLAlchemyError as fault:
        logger.error("job %d: could not record its failure: %s", claim.job.id, reason(fault))
        return None


T = TypeVar("T")
# Backoff between tries of a write the store refused for a moment: doubling, capped.
FIRST_RETRY_S = 0.2
LAST_RETRY_S = 3.0


def retrying(write: Callable[[], T], settings: Settings | None) -> T:
    """``write()``, tried again with backoff while the store refuses it for a moment (for about
    a lease: after that another worker may own the job); permanent faults are raised at once."""
    patience = settings.lease_s if settings is not None else 15.0
    deadline = time.monotonic() + patience
    delay = FIRST_RETRY_S
    while True:
        try:
            return write()
        except SQLAlchemyError as error:
            if not is_transient(error) or time.monotonic() + delay > deadline:
                raise
            logger.warning("the store refused a write for now (%s); trying again", reason(error))
            time.sleep(delay)
            delay = min(2 * delay, LAST_RETRY_S)


@contextlib.contextmanager
def heartbeat(store: JobStore, claim: Claim, settings: Settings) -> Iterator[None]:
    """Renew the job's lease from a thread every third of a lease while the block runs, so a
    long compiled step or a slow write never lets it lapse, and a dead worker's lease does
    soon (its job runs again once the sweeper sees it)."""
    done = threading.Event()

    def beat() -> None:
        while not done.wait(settings.lease_s / 3):
            try:
                store.renew(claim, lease_s=settings.lease_s)
            except LeaseLost:
                return
            except SQLAlchemyError as error:
                logger.warning("job %d: heartbeat missed (%s)", claim.job.id, reason(error))

    thread = threading.Thread(target=beat, name=f"heartbeat-{claim.job.id}", daemon=True)
    thread.start()
    try:
        yield
    finally:
        done.set()
        thread.join()
