"""End to end: a ``python -m worker`` process with ``NANONAV_RETENTION_DAYS`` deletes what
ended before it, and runs and keeps what is new."""

from __future__ import annotations

import time
from collections.abc import Callable
from datetime import UTC, datetime, timedelta

import pytest

from tests.conftest import Api
from tests.e2e.test_jobs import TINY, submit, wait_for
from tests.processes import FIRST_JOB_S, Worker
from tests.store.test_retention import succeeded

pytestmark = pytest.mark.timeout(240)


def test_a_worker_deletes_what_ended_before_its_retention(
    api: Api, start_worker: Callable[..., Worker]
) -> None:
    old = succeeded(api.store, at=datetime.now(UTC) - timedelta(days=3))
    new = submit(api, TINY)
    worker = start_worker(NANONAV_RETENTION_DAYS="2")
    job, _ = wait_for(api, new, lambda j: j["status"] == "succeeded", FIRST_JOB_S)
    assert job["status"] == "succeeded"
    deadline = time.monotonic() + 30
    while api.client.get(f"/jobs/{old}").status_code != 404:
        assert time.monotonic() < deadline, worker.text()
        time.sleep(0.1)
    assert api.client.get(f"/jobs/{old}/metrics").status_code == 404
    assert api.client.get(f"/jobs/{new}/metrics").status_code == 200
    # the pass logs what it deleted once its transaction has committed: a moment after the job
    # is gone (a busy machine once read the log in between)
    said = "retention: deleted 1 jobs and 0 studies that ended before"
    while said not in worker.text():
        assert time.monotonic() < deadline, worker.text()
        time.sleep(0.1)
