"""One status vocabulary (``nanonav.status``): the store's enum holds exactly its values, in its
order, and the client, the API's answers and a study's report speak it, so a status added to
one and not the others fails here, not in a user's script."""

from __future__ import annotations

from typing import get_args

from nanonav import client
from nanonav.status import FINISHED, STATUSES
from nanonav.store.models import ENDED, JobStatus
from nanonav.studies import report
from service import schemas


def test_the_store_the_schemas_the_report_and_the_client_share_one_status_list() -> None:
    assert tuple(status.value for status in JobStatus) == STATUSES
    assert get_args(client.Status) == STATUSES
    for model in (schemas.Job, schemas.StudySummary, schemas.Study):  # what the API answers
        assert get_args(model.model_fields["status"].annotation) == STATUSES, model
    assert get_args(report.StudyStatus) == STATUSES
    assert {status.value for status in JobStatus if status.finished} == FINISHED
    assert {status.value for status in ENDED} == FINISHED
