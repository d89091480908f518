"""Sending webhooks, from a thread of each worker process: a receiver that is slow or down
delays only other webhooks, never a simulation.

Each pass makes due the webhooks of jobs and studies that ended, then sends every due one, a
signed JSON ``POST`` each (see ``nanonav.webhooks``). A 2xx answer delivers it; anything else
(another status, a timeout, a refused connection, an address not allowed, an error nobody
foresaw) is tried again after a doubling wait, until ``webhook_attempts`` tries failed; a URL
the allow-list does not permit is given up at once. Redirects are not followed: a receiver
answers where it was named, on a host the allow-list permits.

The host is resolved for each try and every address it resolves to must be allowed
(``nanonav.webhooks.address_refusal``); the request then goes to the first of those addresses
that takes the connection, with the name in the ``Host`` header and, for https, as the TLS
server name that the certificate is checked against. No second lookup happens between the
check and the connection, so a name cannot be pointed elsewhere in between (DNS rebinding).
Each request closes its connection: a kept-alive one to an address would otherwise carry the
next request for another name, under the certificate checked for the first.

A try that raises is a failed try, and a pass that raises is logged and followed by the next;
a sender thread that stops anyway is started again by ``supervise_deliveries``. Progress is
recorded on the worker's row, for /healthz.
"""

from __future__ import annotations

import json
import logging
import socket
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, Protocol

import httpx
from sqlalchemy.exc import SQLAlchemyError

from nanonav import __version__
from nanonav.settings import Settings
from nanonav.store.deliveries import DeliveryClaim, DeliveryStore
from nanonav.store.faults import reason
from nanonav.store.queue import PRESENCE_INTERVAL_S
from nanonav.webhooks import (
    DELIVERY_HEADER,
    EVENT_HEADER,
    SIGNATURE_HEADER,
    Network,
    Refused,
    address_refusal,
    callback_target,
    host_address,
    retry_delay_s,
    signature,
)

logger = logging.getLogger(__name__)

DELIVERY_INTERVAL_S = 1.0
# How long the supervisor waits before it starts a sender that stopped again.
RESTART_S = 5.0

# What the sender resolves a host with: ``socket.getaddrinfo``, or one a test gives.
Resolver = Callable[[str, int], Sequence[tuple[Any, ...]]]


class Sender(Protocol):
    """What ``supervise_deliveries`` keeps running: ``run_deliveries``, or one a test gives."""

    def __call__(
        self,
        database: DeliveryStore,
        settings: Settings,
        stopped: threading.Event,
        *,
        owner: str | None = ...,
    ) -> None: ...


@dataclass(frozen=True)
class Try:
    """How one try went: the receiver's status, why it failed (None: delivered), and whether
    no later try could go better."""

    status: int | None
    error: str | None
    final: bool = False


class Pulse:
    """Records on the worker's row, at most every PRESENCE_INTERVAL_S, that its sender made
    progress; a sender without an owner records nothing."""

    def __init__(self, store: DeliveryStore, owner: str | None) -> None:
        self._store = store
        self._owner = owner
        self._last = -PRESENCE_INTERVAL_S

    def __call__(self) -> None:
        now = time.monotonic()
        if self._owner is None or now - self._last < PRESENCE_INTERVAL_S:
            return
        self._store.sender_passed(self._owner)
        self._last = now


def deliver_due(
    store: DeliveryStore,
    settings: Settings,
    client: httpx.Client,
    *,
    resolver: Resolver = socket.getaddrinfo,
    progress: Callable[[], None] | None = None,
) -> int:
    """Make due what ended, then send every webhook due now; returns how many were tried.
    ``progress`` is called after each try and at the end of the pass."""
    store.promote()
    tried = 0
    lease_s = settings.webhook_timeout_s * 3 + 5
    while (claim := store.claim(lease_s=lease_s)) is not None:
        try:
            outcome = _send(claim, settings, client, resolver)
        except Exception as error:  # this try failed; the next webhook still goes
            logger.exception("webhook %d (%s): the try raised", claim.id, claim.event)
            outcome = Try(None, f"could not be sent: {type(error).__name__}: {error}")
        last = claim.attempts + 1 >= settings.webhook_attempts
        final = outcome.error is None or outcome.final or last
        retry = None if final else retry_delay_s(claim.attempts + 1, settings.webhook_retry_s)
        store.settle(claim, status=outcome.status, error=outcome.error, retry_in_s=retry)
        tried += 1
        if outcome.error is None:
            logger.info("webhook %d (%s) delivered", claim.id, claim.event)
        else:
            logger.info("webhook %d (%s) try %d failed: %s", claim.id, claim.event,
                        claim.attempts + 1, outcome.error)  # fmt: skip
        if progress is not None:
            progress()
    if progress is not None:
        progress()
    return tried


def _send(
    claim: DeliveryClaim, settings: Settings, client: httpx.Client, resolver: Resolver
) -> Try:
    """One try, to the first checked address of the host that takes the connection."""
    try:
        target = callback_target(claim.url, settings.webhook_hosts)
    except Refused as why:
        return Try(None, f"not sent: {why}", final=True)  # the URL never changes
    host = target.raw_host.decode("ascii")
    port = target.port or (443 if target.scheme == "https" else 80)
    try:
        addresses = checked_addresses(host, port, settings.webhook_addresses, resolver)
    except Refused as why:
        return Try(None, f"not sent: {why}")  # what the name resolves to may change
    except (OSError, UnicodeError) as error:
        return Try(None, f"could not resolve {host}: {error}")
    assert settings.webhook_secret is not None  # settings refuse hosts without a secret
    body = json.dumps(claim.payload, separators=(",", ":"), sort_keys=True).encode()
    headers = {
        "Host": target.netloc.decode("ascii"),
        "Connection": "close",
        "Content-Type": "application/json",
        "User-Agent": f"nanonav/{__version__}",
        EVENT_HEADER: claim.event,
        DELIVERY_HEADER: str(claim.id),
        SIGNATURE_HEADER: signature(
            settings.webhook_secret.get_secret_value(), body, int(time.time())
        ),
    }
    # httpcore takes sni_hostname as the TLS server name, which the certificate is checked
    # against too; without it, it would be the address the URL now holds.
    tls = {"sni_hostname": host.removesuffix(".")} if target.scheme == "https" else {}
    failed = Try(None, f"{host} resolves to no address")
    for address in addresses:
        try:
            response = client.post(
                target.copy_with(host=address), content=body, headers=headers, extensions=tls
            )
        except httpx.ConnectError as error:  # refused or unreachable: the next address
            failed = Try(None, f"could not connect to {address}: {type(error).__name__}: {error}")
            continue
        except httpx.TimeoutException:
            return Try(None, f"no answer within {settings.webhook_timeout_s:g} s from {address}")
        except httpx.HTTPError as error:
            return Try(None, f"could not connect to {address}: {type(error).__name__}: {error}")
        if response.is_success:
            return Try(response.status_code, None)
        return Try(response.status_code, f"the receiver answered HTTP {response.status_code}")
    return failed


def checked_addresses(
    host: str, port: int, allowed: Sequence[Network], resolver: Resolver
) -> list[str]:
    """The addresses ``host`` stands for now, in the resolver's order, each one allowed;
    ``Refused`` naming the first that is not: a name that resolves to one address this server
    may not call is not called at any of its addresses."""
    written = host_address(host)
    if written is not None:
        why = address_refusal(written, allowed)
        if why is not None:
            raise Refused(f"{written} is {why}")
        return [str(written)]
    found = list(dict.fromkeys(str(info[4][0]) for info in resolver(host, port)))
    for address in found:
        why = address_refusal(address, allowed)
        if why is not None:
            raise Refused(f"{host} resolves to {address}, {why}")
    return found


def run_deliveries(
    database: DeliveryStore,
    settings: Settings,
    stopped: threading.Event,
    *,
    owner: str | None = None,
    resolver: Resolver = socket.getaddrinfo,
) -> None:
    """Send webhooks every ``DELIVERY_INTERVAL_S`` until ``stopped``, recording the progress
    on the row of the worker ``owner``."""
    timeout = httpx.Timeout(settings.webhook_timeout_s)
    pulse = Pulse(database, owner)
    with httpx.Client(timeout=timeout, follow_redirects=False, trust_env=False) as client:
        while not stopped.wait(DELIVERY_INTERVAL_S):
            try:
                deliver_due(database, settings, client, resolver=resolver, progress=pulse)
            except SQLAlchemyError as error:
                logger.warning("could not send webhooks (%s); retrying", reason(error))
            except Exception:
                logger.exception("a pass of the webhook sender failed; trying again")


def supervise_deliveries(
    database: DeliveryStore,
    settings: Settings,
    stopped: threading.Event,
    *,
    owner: str | None = None,
    sender: Sender = run_deliveries,
    restart_s: float = RESTART_S,
) -> None:
    """Keep a sender thread running until ``stopped``: one that ends before (on an error no
    try caught) is logged and started again after ``restart_s``."""
    while True:
        thread = threading.Thread(
            target=_logged,
            args=(sender, database, settings, stopped, owner),
            name="webhook-sender",
            daemon=True,
        )
        thread.start()
        thread.join()
        if stopped.is_set():
            return
        logger.error("the webhook sender stopped; starting it again in %g s", restart_s)
        if stopped.wait(restart_s):
            return


def _logged(
    sender: Sender,
    database: DeliveryStore,
    settings: Settings,
    stopped: threading.Event,
    owner: str | None,
) -> None:
    try:
        sender(database, settings, stopped, owner=owner)
    except BaseException:
        logger.exception("the webhook sender stopped on an error")
