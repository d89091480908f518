"""The job statuses the client, the API's schemas and a study's report name are the store's:
each has its own list (the client imports no store), so a status added to one and not the
others fails here, not in a user's script."""

from __future__ import annotations

from typing import get_args

from nanonav import client
from nanonav.store import JobStatus
from nanonav.studies import report
from service import schemas


def test_every_list_of_job_statuses_is_the_stores() -> None:
    stored = tuple(status.value for status in JobStatus)
    assert get_args(client.Status) == stored
    assert get_args(schemas.Status) == stored
    assert stored == report.STATUSES
    assert get_args(report.StudyStatus) == stored
