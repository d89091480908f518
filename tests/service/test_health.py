"""/healthz on webhooks: how many are due and since when, when a worker's sender last made
progress, and a note when some are due but no sender is sending them; still 200 then, as the
jobs still run."""

from __future__ import annotations

from datetime import UTC, datetime, timedelta

from nanonav.settings import Settings
from nanonav.store.deliveries import DeliveryStore
from tests.conftest import Api
from tests.service.test_callbacks import HOOK
from tests.service.test_callbacks import api_settings as api_settings  # webhooks allowed


def test_healthz_counts_due_webhooks_and_says_when_no_sender_sends_them(api: Api) -> None:
    quiet = api.client.get("/healthz").json()
    assert quiet["webhooks"] == {
        "due": 0, "retrying": 0, "oldest_due_at": None, "overdue_s": None,
        "last_pass_at": None, "window_s": 60.0,
    }  # fmt: skip
    assert "no worker has been seen" in quiet["note"]
    api.store.worker_seen("host:7", started_at=datetime.now(UTC), ready=False)
    preparing = api.client.get("/healthz").json()
    assert preparing["workers"] == {"seen": 0, "preparing": 1, "window_s": 30.0}
    assert preparing["note"].startswith("1 worker is preparing the engine (a first start")
    api.store.worker_seen("host:7", started_at=datetime.now(UTC))
    assert api.client.get("/healthz").json()["note"] is None
    job_id = api.client.post("/jobs", params={"callback_url": HOOK}, json={}).json()["id"]
    api.client.post(f"/jobs/{job_id}/cancel")
    response = api.client.get("/healthz")
    assert response.status_code == 200
    health = response.json()
    assert health["status"] == "ok"
    webhooks = health["webhooks"]
    assert webhooks["due"] == 1 and webhooks["last_pass_at"] is None
    ended = api.store.get(job_id).finished_at
    assert ended is not None and datetime.fromisoformat(webhooks["oldest_due_at"]) == ended
    assert 0 <= webhooks["overdue_s"] < 30
    assert health["note"].startswith("1 webhook is due (the oldest for ")
    assert "no worker has sent webhooks in the last 60 s" in health["note"]
    now = datetime.now(UTC)
    deliveries = DeliveryStore(api.store.engine)
    deliveries.sender_passed("host:7", now=now)
    health = api.client.get("/healthz").json()
    assert datetime.fromisoformat(health["webhooks"]["last_pass_at"]) == now
    assert health["note"] is None
    deliveries.sender_passed("host:7", now=now - timedelta(seconds=300))
    health = api.client.get("/healthz").json()
    assert health["status"] == "ok" and "(the last one 300 s ago)" in health["note"]


def test_a_process_of_several_has_a_minute_to_answer_its_supervisor() -> None:
    """uvicorn's supervisor kills a process that does not answer its health check in time;
    its own 5 s killed processes still importing the engine on a loaded machine, over and
    over (43 restarts, the API unreachable for minutes)."""
    from service.server import APP, server_config

    config = server_config(APP, Settings(), factory=True, workers=2)
    assert config.timeout_worker_healthcheck >= 60
