"""Sending webhooks, from a thread of each worker process: a receiver that is slow or down
delays only other webhooks, never a simulation.

Each pass makes due the webhooks of jobs and studies that ended, then sends every due one, a
signed JSON ``POST`` each (see ``nanonav.webhooks``). A 2xx answer delivers it; anything else
(another status, a timeout, a refused connection) is tried again after a doubling wait, until
``webhook_attempts`` tries failed. Redirects are not followed: a receiver answers where it was
named, on a host the allow-list permits.
"""

from __future__ import annotations

import json
import logging
import threading
import time

import httpx
from sqlalchemy.exc import SQLAlchemyError

from nanonav import __version__
from nanonav.settings import Settings
from nanonav.store.deliveries import DeliveryClaim, DeliveryStore
from nanonav.store.faults import reason
from nanonav.webhooks import (
    DELIVERY_HEADER,
    EVENT_HEADER,
    SIGNATURE_HEADER,
    refusal,
    retry_delay_s,
    signature,
)

logger = logging.getLogger(__name__)

DELIVERY_INTERVAL_S = 1.0


def deliver_due(store: DeliveryStore, settings: Settings, client: httpx.Client) -> int:
    """Make due what ended, then send every webhook due now; returns how many were tried."""
    store.promote()
    tried = 0
    lease_s = settings.webhook_timeout_s * 3 + 5
    while (claim := store.claim(lease_s=lease_s)) is not None:
        status, error = _send(claim, settings, client)
        final = error is None or claim.attempts + 1 >= settings.webhook_attempts
        retry = None if final else retry_delay_s(claim.attempts + 1, settings.webhook_retry_s)
        if error is not None and refusal(claim.url, settings.webhook_hosts) is not None:
            retry = None  # the allow-list no longer permits it: no try ever will
        store.settle(claim, status=status, error=error, retry_in_s=retry)
        tried += 1
        if error is None:
            logger.info("webhook %d (%s) delivered", claim.id, claim.event)
        else:
            logger.info("webhook %d (%s) try %d failed: %s", claim.id, claim.event,
                        claim.attempts + 1, error)  # fmt: skip
    return tried


def _send(
    claim: DeliveryClaim, settings: Settings, client: httpx.Client
) -> tuple[int | None, str | None]:
    """One try: the receiver's status, and why it failed (None if it took the webhook)."""
    refused = refusal(claim.url, settings.webhook_hosts)
    if refused is not None:
        return None, f"not sent: {refused}"
    assert settings.webhook_secret is not None  # settings refuse hosts without a secret
    body = json.dumps(claim.payload, separators=(",", ":"), sort_keys=True).encode()
    headers = {
        "Content-Type": "application/json",
        "User-Agent": f"nanonav/{__version__}",
        EVENT_HEADER: claim.event,
        DELIVERY_HEADER: str(claim.id),
        SIGNATURE_HEADER: signature(
            settings.webhook_secret.get_secret_value(), body, int(time.time())
        ),
    }
    try:
        response = client.post(claim.url, content=body, headers=headers)
    except httpx.TimeoutException:
        return None, f"no answer within {settings.webhook_timeout_s:g} s"
    except httpx.HTTPError as error:
        return None, f"could not connect: {type(error).__name__}: {error}"
    if response.is_success:
        return response.status_code, None
    return response.status_code, f"the receiver answered HTTP {response.status_code}"


def run_deliveries(database: DeliveryStore, settings: Settings, stopped: threading.Event) -> None:
    """Send webhooks every ``DELIVERY_INTERVAL_S`` until ``stopped``."""
    timeout = httpx.Timeout(settings.webhook_timeout_s)
    with httpx.Client(timeout=timeout, follow_redirects=False, trust_env=False) as client:
        while not stopped.wait(DELIVERY_INTERVAL_S):
            try:
                deliver_due(database, settings, client)
            except SQLAlchemyError as error:
                logger.warning("could not send webhooks (%s); retrying", reason(error))
