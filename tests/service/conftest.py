"""Jobs run to their end in the test's process, as a worker would, for the API to read."""

from __future__ import annotations

import threading
from typing import Any

import pytest

from nanonav.settings import Settings
from nanonav.store import JobStatus, JobStore
from tests.conftest import Api
from worker.job import run_job

TINY: dict[str, Any] = {"robots": {"count": 2}, "learning": {"episodes": 2, "max_steps": 60}}


def ran(store: JobStore, settings: Settings, scenario: dict[str, Any]) -> int:
    """A job run to its end in this process; its id."""
    job = store.enqueue(scenario, robot_steps=1, episodes=1)
    claim = store.claim("test", lease_s=30)
    assert claim is not None and claim.job.id == job.id
    assert run_job(store, claim, settings, threading.Event()) is not None
    return job.id


@pytest.fixture
def trained(api: Api, api_settings: Settings) -> int:
    """A succeeded Q-learning job of two robots sharing one 'behaviors' table."""
    job_id = ran(api.store, api_settings, TINY)
    assert api.store.get(job_id).status is JobStatus.SUCCEEDED
    return job_id
