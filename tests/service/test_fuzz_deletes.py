"""Whatever a client sends to the delete routes, the answer is one the OpenAPI document states,
never a 5xx: generated requests over a real SQLite file of its own that holds jobs and studies
in every state a delete meets (finished, running, queued, of a study, ended or not), so that
small ids reach the routes' real work."""

from __future__ import annotations

import tempfile
from pathlib import Path
from typing import Any

import schemathesis
from hypothesis import HealthCheck, settings
from schemathesis.checks import not_a_server_error
from schemathesis.specs.openapi.checks import status_code_conformance

from nanonav.settings import Settings
from nanonav.store import JobStore, Outcome, StudyJob, StudyStore
from nanonav.store.migrate import upgrade
from service.app import create_app

# Schemathesis reads the schema when the module is collected, so the database is made then.
_DIRECTORY = tempfile.TemporaryDirectory(prefix="nanonav-fuzz-deletes-")
_URL = f"sqlite:///{Path(_DIRECTORY.name) / 'nanonav.db'}"
_DONE = Outcome(completed=True, metrics={}, trajectory=None, qtable=None)


def _seeded_settings() -> Settings:
    """Study 1 ended (its job 1 succeeded); job 2 succeeded, 3 running, 4 queued; study 2 queued."""
    upgrade(_URL)
    store = JobStore.from_url(_URL)
    studies = StudyStore(store.engine)
    one_job = [StudyJob({"seed": 0}, robot_steps=1, episodes=1, point=0, seed=0)]
    studies.create(name="ended", spec={}, jobs=one_job)
    for seed in range(3):
        store.enqueue({"seed": seed}, robot_steps=1, episodes=1)
    for _ in range(2):  # claims go oldest first: jobs 1 and 2
        claimed = store.claim("fuzz", lease_s=3600)
        assert claimed is not None
        store.finish(claimed, _DONE)
    assert store.claim("fuzz", lease_s=3600) is not None  # job 3
    studies.create(name="queued", spec={}, jobs=one_job)
    store.close()
    return Settings(database_url=_URL, max_body_bytes=64 * 1024)


schema = schemathesis.openapi.from_asgi("/openapi.json", create_app(_seeded_settings())).include(
    method="DELETE"
)


@schema.parametrize()
@settings(max_examples=25, deadline=None, suppress_health_check=list(HealthCheck))
def test_no_delete_gives_a_server_error_or_an_undocumented_status(
    case: schemathesis.Case[Any],
) -> None:
    case.call_and_validate(checks=[not_a_server_error, status_code_conformance])
