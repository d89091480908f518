"""The claim loop, its signals, and ``--concurrency`` worker processes under one supervisor.

SIGTERM or SIGINT asks a worker to stop: the job it runs stops at its next progress check and
goes back to the queue (unless it has just finished), then the process exits.
"""

from __future__ import annotations

import contextlib
import hashlib
import logging
import multiprocessing
import os
import signal
import socket
import subprocess
import sys
import threading
import time
from datetime import UTC, datetime, timedelta
from functools import partial
from types import FrameType
from typing import Any, NoReturn

import numpy as np
from numpy.typing import NDArray
from sqlalchemy.exc import SQLAlchemyError

from nanonav.children import die_with_parent
from nanonav.engine import simulate
from nanonav.engine.compiled import CACHE
from nanonav.rl.evaluate import evaluate
from nanonav.scenario import Scenario, Steering
from nanonav.settings import Settings
from nanonav.store import JobStore, RetentionStore
from nanonav.store.deliveries import DeliveryStore
from nanonav.store.faults import reason
from nanonav.store.queue import PRESENCE_INTERVAL_S
from nanonav.store.retention import RETENTION_BATCH
from nanonav.store.wakeups import Wakeups
from worker.deliveries import supervise_deliveries
from worker.job import run_job

logger = logging.getLogger(__name__)

LOG_FORMAT = "%(asctime)s %(levelname)s [%(process)d] %(name)s: %(message)s"
# How often a worker looks for jobs whose lease ran out (their worker died), whether it is busy
# or not: with the default 15 s lease a killed worker's job runs again within about 20 s.
RECOVERY_INTERVAL_S = 3.0
# How long a stopping worker waits for its housekeeping threads, all of them together.
HOUSEKEEPING_STOP_S = 5.0
# How often a worker with a retention deletes what ended before it, and how long and how many
# batches (of RETENTION_BATCH jobs, a transaction each) one pass may take before the next sweep.
RETENTION_INTERVAL_S = 60.0
RETENTION_PASS_S = 1.0
RETENTION_BATCHES = 50

WARM_UP = {
    "robots": {"count": 1},
    "obstacles": {"count": 0},
    "learning": {"episodes": 0, "max_steps": 2},
}
# A network's evaluation: the worlds stepped from outside, deciding by action number in the
# lattice and by a turn in the active Brownian physics
DECIDED: tuple[tuple[dict[str, Any], Steering], ...] = (
    (WARM_UP, "discrete"),
    ({**WARM_UP, "physics": {"model": "active_brownian"}}, "continuous"),
)


def warm_up() -> None:
    """Compile (or load from cache) every path a job can take before the first job is
    claimed: ``simulate``'s kernel, and the worlds' step that evaluates a network (a job
    never waits on a compile, its lease held)."""
    simulate(Scenario.model_validate(WARM_UP))
    for scenario, steering in DECIDED:
        parts = 2 if steering == "continuous" else 0
        evaluate(Scenario.model_validate(scenario), partial(_nothing, parts), steering=steering)


def prepare(shutdown: threading.Event) -> bool:
    """``warm_up`` in a process of its own first, which compiles what the cache lacks, then
    here, which loads it: what compiling takes (up to a gigabyte) is freed with that process,
    and a worker holds what it runs (about 0.35 GB). Once a worker was ready on this cache,
    the next loads it at once. Should that process fail, this one compiles for itself. False
    if ``shutdown`` came first (the compile stopped)."""
    started = time.monotonic()
    ready = CACHE / f"worker-ready-{_warm_up_digest()}"
    if not ready.exists():
        logger.info("compiling the engine for this machine, once: about a minute on two cores "
                    "(later starts load it in seconds)")  # fmt: skip
        compiling = subprocess.Popen(
            [sys.executable, "-c",
             f"from worker.loop import compile_alone; compile_alone({os.getpid()})"],
        )  # fmt: skip
        while compiling.poll() is None:
            if shutdown.wait(0.2):
                compiling.kill()
                compiling.wait()
                return False
        if compiling.returncode == 0:
            with contextlib.suppress(OSError):
                ready.touch()
        else:
            logger.warning("compiling in a process of its own failed (%s); compiling here",
                           compiling.returncode)  # fmt: skip
    warm_up()
    logger.info("the engine is ready (%.1f s)", time.monotonic() - started)
    return not shutdown.is_set()


def compile_alone(parent: int) -> None:
    """``prepare``'s process that compiles: it goes with the worker, should the worker be
    killed while it compiles."""
    die_with_parent(parent)
    warm_up()


def _warm_up_digest() -> str:
    """What ``warm_up`` runs, as a digest: a worker that runs more finds its cache not ready."""
    text = repr((WARM_UP, DECIDED)).encode()
    return hashlib.sha256(text).hexdigest()[:12]


def _nothing(parts: int, rows: NDArray[np.float64]) -> NDArray[Any]:
    """A decision for each row: action 0, or no turn (``parts`` numbers of zero)."""
    if parts:
        return np.zeros((rows.shape[0], parts))
    return np.zeros(rows.shape[0], dtype=np.int64)


def work(settings: Settings, shutdown: threading.Event, *, max_jobs: int | None = None) -> int:
    """Claim and run jobs until ``shutdown`` is set (or ``max_jobs`` ran); returns jobs run.
    Idle, it waits for the queue's notification (PostgreSQL) or the poll interval."""
    owner = f"{socket.gethostname()}:{os.getpid()}"
    store = JobStore.from_url(settings.database_url, busy_timeout_s=settings.store_busy_timeout_s)
    ran = 0
    stopped = threading.Event()
    housekeeping = [
        threading.Thread(target=_announce, args=(store, owner, stopped), name="presence",
                         kwargs={"trains": settings.worker_trains}, daemon=True),
        threading.Thread(target=_sweep, args=(store, settings, stopped), name="sweeper",
                         daemon=True),
    ]  # fmt: skip
    if settings.webhook_hosts:  # a worker without the webhook settings leaves them to others
        deliveries = DeliveryStore(store.engine)
        housekeeping.append(threading.Thread(target=supervise_deliveries, name="webhooks",
                                             args=(deliveries, settings, stopped),
                                             kwargs={"owner": owner}, daemon=True))  # fmt: skip
    for thread in housekeeping:
        thread.start()
    wakeups = Wakeups(store.engine)
    if wakeups.listen():
        logger.info("listening for queued jobs; polling every %g s too", settings.poll_interval_s)
    try:
        while not shutdown.is_set() and (max_jobs is None or ran < max_jobs):
            try:
                claim = store.claim(owner, lease_s=settings.lease_s, trains=settings.worker_trains)
            except SQLAlchemyError as error:
                logger.warning("the store is unavailable (%s); retrying", reason(error))
                shutdown.wait(max(settings.poll_interval_s, 1.0))
                continue
            if claim is None:
                wakeups.wait(settings.poll_interval_s, shutdown)
                continue
            logger.info("job %d: claimed (attempt %d)", claim.job.id, claim.job.attempts)
            try:
                record = run_job(store, claim, settings, shutdown)
            except SQLAlchemyError:
                logger.exception("job %d: the store failed while it ran", claim.job.id)
                continue
            ran += 1
            if record is not None:
                logger.info("job %d: %s", record.id, record.status.value)
    finally:
        stopped.set()
        wakeups.close()
        join_within(housekeeping, HOUSEKEEPING_STOP_S)
        with contextlib.suppress(SQLAlchemyError):
            store.worker_gone(owner)
        store.close()
    return ran


def join_within(threads: list[threading.Thread], timeout_s: float) -> None:
    """Wait at most ``timeout_s`` in all for ``threads`` to stop, naming those that did not: a
    thread held in a store call (a locked SQLite file waits up to ``store_busy_timeout_s``) or a
    webhook's request must not hold a worker that was asked to stop; they are daemons, and what
    they held is leased, so another worker takes it up."""
    deadline = time.monotonic() + timeout_s
    for thread in threads:
        thread.join(max(0.0, deadline - time.monotonic()))
    if late := [thread.name for thread in threads if thread.is_alive()]:
        logger.warning("stopping without waiting for %s", ", ".join(late))


def _announce(
    store: JobStore,
    owner: str,
    stopped: threading.Event,
    *,
    ready: bool = True,
    trains: bool = False,
) -> None:
    """Say every few seconds that this worker is alive, whether it runs a job or waits (or,
    not ``ready``, prepares the engine), and whether it trains networks."""
    started = datetime.now(UTC)
    while True:
        try:
            store.worker_seen(owner, started_at=started, ready=ready, trains=trains)
        except SQLAlchemyError:
            logger.warning("could not record that this worker is alive; retrying")
        if stopped.wait(PRESENCE_INTERVAL_S):
            return


def _sweep(store: JobStore, settings: Settings, stopped: threading.Event) -> None:
    """Queue again the jobs of workers that stopped answering, on a timer of its own: a busy
    worker sweeps as often as an idle one; with a retention, also delete what ended before it,
    less often (a look at every finished job costs more than one at the running ones)."""
    retention = None if settings.retention_days is None else RetentionStore(store.engine)
    next_expiry = time.monotonic()
    while not stopped.wait(RECOVERY_INTERVAL_S):
        try:
            if recovered := store.recover_expired(max_attempts=settings.max_attempts):
                logger.info("recovered %d job(s) whose worker stopped answering", recovered)
        except SQLAlchemyError as error:
            logger.warning("could not look for stalled jobs (%s); retrying", reason(error))
        if retention is not None and time.monotonic() >= next_expiry:
            _, done = expire(retention, settings, stopped)
            # a pass cut short goes on at the next sweep, so a backlog clears in steps
            next_expiry = time.monotonic() + (RETENTION_INTERVAL_S if done else 0.0)


def expire(
    retention: RetentionStore, settings: Settings, stopped: threading.Event
) -> tuple[int, bool]:
    """Delete, batch after batch, what ended more than ``retention_days`` ago, for at most
    RETENTION_PASS_S or RETENTION_BATCHES batches, so that the sweeper's other work (jobs of
    dead workers) is never held up long; returns the jobs deleted, and whether nothing is left."""
    assert settings.retention_days is not None
    before = datetime.now(UTC) - timedelta(days=settings.retention_days)
    deadline = time.monotonic() + RETENTION_PASS_S
    deleted = studies = 0
    done = False
    try:
        for _ in range(RETENTION_BATCHES):
            batch = retention.expire(before=before, batch=RETENTION_BATCH)
            deleted, studies = deleted + batch.jobs, studies + batch.studies
            if not batch.any:
                done = True
                break
            if stopped.is_set() or time.monotonic() > deadline:
                break
    except SQLAlchemyError as error:
        logger.warning("could not delete expired results (%s); retrying later", reason(error))
        done = True  # tried again at the next pass, not at once
    if deleted or studies:
        logger.info("retention: deleted %d jobs and %d studies that ended before %s",
                    deleted, studies, before.isoformat(timespec="seconds"))  # fmt: skip
    return deleted, done


def _on_signals(shutdown: threading.Event) -> None:
    def stop(signum: int, frame: FrameType | None) -> None:
        logger.info("signal %d: stopping after the current step", signum)
        shutdown.set()

    signal.signal(signal.SIGTERM, stop)
    signal.signal(signal.SIGINT, stop)


def run_worker(settings: Settings, *, orphan_check: bool = False) -> None:
    """One worker in this process, until SIGTERM or SIGINT (or, under a supervisor, until the
    supervisor is gone)."""
    shutdown = threading.Event()
    _on_signals(shutdown)
    if orphan_check:
        _stop_when_orphaned(shutdown)
    if settings.worker_nice:
        os.nice(settings.worker_nice)
    if not _prepare_seen(settings, shutdown):
        logger.info("stopped before the engine was ready")
        return
    logger.info("worker %d ready on %s", os.getpid(), _safe_url(settings))
    work(settings, shutdown)


def _prepare_seen(settings: Settings, shutdown: threading.Event) -> bool:
    """``prepare``, saying all along that this worker is alive and preparing (``/healthz``
    counts it apart from those ready); False, and forgotten, if ``shutdown`` came first."""
    owner = f"{socket.gethostname()}:{os.getpid()}"
    store = JobStore.from_url(settings.database_url, busy_timeout_s=settings.store_busy_timeout_s)
    prepared = threading.Event()
    presence = threading.Thread(target=_announce, args=(store, owner, prepared),
                                kwargs={"ready": False}, name="presence", daemon=True)  # fmt: skip
    presence.start()
    try:
        ready = prepare(shutdown)
    finally:
        prepared.set()
        presence.join()
    if not ready:
        with contextlib.suppress(SQLAlchemyError):
            store.worker_gone(owner)
    store.close()
    return ready


def _child(settings_data: dict[str, Any]) -> None:
    logging.basicConfig(level=logging.INFO, format=LOG_FORMAT)
    run_worker(Settings(**settings_data), orphan_check=True)
    exit_at_once()


def exit_at_once(code: int = 0) -> NoReturn:
    """End a worker's process once it has stopped (its job given back, its store closed),
    without the interpreter's teardown: unloading numba, LLVM and the learners' libraries took
    0.6 s on an idle machine and 8 s on a loaded one, time that a supervisor or an orchestrator
    waiting on SIGTERM counts against the worker, with nothing left to do in it."""
    logging.shutdown()
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(code)


ORPHAN_CHECK_S = 1.0


def _stop_when_orphaned(shutdown: threading.Event) -> None:
    """A supervised worker stops (giving its job back) when its supervisor dies: nobody would
    replace it or stop it otherwise."""
    parent = os.getppid()

    def watch() -> None:
        while not shutdown.wait(ORPHAN_CHECK_S):
            if os.getppid() != parent:
                logger.warning("the supervisor (%d) is gone; stopping", parent)
                shutdown.set()

    threading.Thread(target=watch, name="orphan-check", daemon=True).start()


def supervise(settings: Settings, concurrency: int) -> None:
    """``concurrency`` worker processes; a child that dies is replaced; a signal stops all."""
    if concurrency <= 1:
        run_worker(settings)
        return
    shutdown = threading.Event()
    _on_signals(shutdown)
    context = multiprocessing.get_context("spawn")
    data = settings.model_dump()

    def start() -> multiprocessing.process.BaseProcess:
        process = context.Process(target=_child, args=(data,), daemon=False)
        process.start()
        return process

    children = [start() for _ in range(concurrency)]
    while not shutdown.wait(0.5):
        for i, child in enumerate(children):
            if not child.is_alive():
                logger.warning(
                    "worker %s exited with %s; starting another", child.pid, child.exitcode
                )
                children[i] = start()
    for child in children:
        if child.is_alive() and child.pid is not None:
            os.kill(child.pid, signal.SIGTERM)
    for child in children:
        child.join()


def _safe_url(settings: Settings) -> str:
    from sqlalchemy.engine import make_url

    return make_url(settings.database_url).render_as_string(hide_password=True)
