"""Whatever a client sends, allowed by the OpenAPI document or not, the answer is never a 5xx:
generated requests against every route, over a real SQLite file that holds a succeeded job and
a study, so that ids such as 1 reach the routes' real work."""

from __future__ import annotations

import tempfile
import threading
from pathlib import Path

import schemathesis
from hypothesis import HealthCheck, settings
from schemathesis.checks import not_a_server_error

from nanonav.settings import Settings
from nanonav.store import JobStore, StudyJob, StudyStore
from nanonav.store.migrate import upgrade
from service.app import create_app
from worker.job import run_job

# Schemathesis reads the schema when the module is collected, so the database is made then.
_DIRECTORY = tempfile.TemporaryDirectory(prefix="nanonav-fuzz-")
_URL = f"sqlite:///{Path(_DIRECTORY.name) / 'nanonav.db'}"


def _seeded_settings() -> Settings:
    upgrade(_URL)
    settings = Settings(database_url=_URL, max_body_bytes=64 * 1024)
    store = JobStore.from_url(_URL)
    store.enqueue({"learning": {"episodes": 1, "max_steps": 30}}, robot_steps=1, episodes=2)
    claim = store.claim("fuzz", lease_s=30)
    assert claim is not None
    run_job(store, claim, settings, threading.Event())
    StudyStore(store.engine).create(
        name="fuzz",
        spec={"grid": {"robots.count": [1, 2]}, "seeds": [0], "base": {}, "name": "fuzz"},
        jobs=[StudyJob({"robots": {"count": n}}, 1, 1, point, 0) for point, n in ((0, 1), (1, 2))],
    )
    store.close()
    return settings


# An event stream of an unfinished job or study never ends by design, so the event routes are
# left out; tests/service/test_event_streams.py pins their 404 and 422 answers. Deletes run in
# tests/service/test_fuzz_deletes.py, so that the job and study every route here reads stay.
schema = (
    schemathesis.openapi.from_asgi("/openapi.json", create_app(_seeded_settings()))
    .exclude(tag="events")
    .exclude(method="DELETE")
)


@schema.parametrize()
@settings(max_examples=15, deadline=None, suppress_health_check=list(HealthCheck))
def test_no_request_gives_a_server_error(case: schemathesis.Case) -> None:
    case.call_and_validate(checks=[not_a_server_error])
