"""One status vocabulary: the store's enum holds exactly the values the schemas, the reports
and the client speak of, in the same order, and the same three never change again."""

from __future__ import annotations

from typing import get_args

from nanonav import client
from nanonav.status import FINISHED, STATUSES
from nanonav.store.models import ENDED, JobStatus
from nanonav.studies import report
from service import schemas


def test_the_store_the_schemas_the_report_and_the_client_share_one_status_list() -> None:
    assert tuple(status.value for status in JobStatus) == STATUSES
    assert get_args(client.Status) == get_args(schemas.Status) == STATUSES
    assert get_args(report.StudyStatus) == STATUSES
    assert {status.value for status in JobStatus if status.finished} == FINISHED
    assert {status.value for status in ENDED} == FINISHED
