"""Sending webhooks to a real HTTP receiver on this machine: signed, retried after failures,
given up after the last attempt, refused when the allow-list no longer permits them; sent only
to addresses the server may call, to the very address that was checked; and a webhook that
cannot be sent is a failed try, never the end of the sender."""

from __future__ import annotations

import json
import logging
import shutil
import socket
import ssl
import subprocess
import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any
from urllib.parse import urlsplit

import httpx
import pytest
from sqlalchemy import update

from nanonav.settings import Settings
from nanonav.store import JobStore
from nanonav.store.deliveries import DeliveryStore
from nanonav.store.models import Delivery, DeliveryState
from nanonav.store.queue import utcnow
from nanonav.webhooks import verify
from tests.conftest import in_ci
from tests.receiver import Receiver, receiving
from worker.deliveries import deliver_due, run_deliveries, supervise_deliveries

SECRET = "kq3N9vTz0bX7mR2sW5yC8dF1gH4jL6pA"
# What the receivers on this machine listen on: localhost may resolve to either.
LOCAL = "127.0.0.0/8,::1"
NAME = "hooks.allowed.test"  # not in any DNS: only the resolver given to the sender knows it


def settings_for(url: str, **changes: Any) -> Settings:
    host = urlsplit(url).netloc
    changes.setdefault("webhook_addresses", LOCAL)
    return Settings(webhook_hosts=(host,), webhook_secret=SECRET, **changes)


def ended_job(store: JobStore, url: str) -> int:
    job = store.enqueue({"seed": 3}, robot_steps=1, episodes=1, callback_url=url)
    store.cancel(job.id)
    return job.id


def stored_as(store: JobStore, job_id: int, url: str) -> None:
    """Give a job's webhook a URL as a server before today's checks may have stored it."""
    with store.engine.begin() as connection:
        connection.execute(update(Delivery).where(Delivery.job_id == job_id).values(url=url))


@dataclass
class Dns:
    """A resolver with the signature of ``socket.getaddrinfo`` that knows one answer, and
    remembers what it was asked."""

    addresses: list[str]
    asked: list[tuple[str, int]] = field(default_factory=list)

    def __call__(self, host: str, port: int) -> list[tuple[Any, ...]]:
        self.asked.append((host, port))
        family = {4: socket.AF_INET, 6: socket.AF_INET6}
        return [
            (family[6 if ":" in a else 4], socket.SOCK_STREAM, 6, "", (a, port))
            for a in self.addresses
        ]


def test_a_webhook_is_posted_signed_with_its_event_and_summary(store: JobStore) -> None:
    deliveries = DeliveryStore(store.engine)
    with receiving() as receiver, httpx.Client() as client:
        job_id = ended_job(store, receiver.url + "?who=me")
        assert deliver_due(deliveries, settings_for(receiver.url), client) == 1
        (got,) = receiver.wait_for(1)
    assert got.path == "/hook?who=me"
    assert got.headers["content-type"] == "application/json"
    assert got.headers["nanonav-event"] == "job.cancelled"
    assert got.headers["host"] == f"localhost:{receiver.port}"
    verify(SECRET, got.headers["nanonav-signature"], got.body, now=time.time())
    body = json.loads(got.body)
    record = deliveries.for_job(job_id)
    assert record is not None and record.state is DeliveryState.DELIVERED
    assert body["id"] == record.id == int(got.headers["nanonav-delivery"])
    assert body["event"] == "job.cancelled" and body["job"]["id"] == job_id
    assert record.last_status == 200 and record.attempts == 1


def test_a_receiver_that_fails_gets_the_same_body_again_after_a_backoff(
    store: JobStore,
) -> None:
    deliveries = DeliveryStore(store.engine)
    with receiving(statuses=[503, 500, 204]) as receiver, httpx.Client() as client:
        job_id = ended_job(store, receiver.url)
        settings = settings_for(receiver.url, webhook_retry_s=0.2)
        assert deliver_due(deliveries, settings, client) == 1
        record = deliveries.for_job(job_id)
        assert record is not None and record.state is DeliveryState.DUE
        assert record.last_error == "the receiver answered HTTP 503"
        assert deliver_due(deliveries, settings, client) == 0  # not before its backoff
        deadline = time.monotonic() + 10
        while len(receiver.got) < 3 and time.monotonic() < deadline:
            deliver_due(deliveries, settings, client)
            time.sleep(0.05)
        got = receiver.wait_for(3)
    assert got[0].body == got[1].body == got[2].body
    assert len({g.headers["nanonav-delivery"] for g in got}) == 1
    record = deliveries.for_job(job_id)
    assert record is not None and record.state is DeliveryState.DELIVERED
    assert record.attempts == 3 and record.last_status == 204 and record.last_error is None


def test_a_webhook_is_given_up_after_its_last_attempt(store: JobStore) -> None:
    deliveries = DeliveryStore(store.engine)
    with receiving(statuses=[500]) as receiver, httpx.Client() as client:
        job_id = ended_job(store, receiver.url)
        settings = settings_for(receiver.url, webhook_retry_s=0.01, webhook_attempts=2)
        deadline = time.monotonic() + 10
        while len(receiver.got) < 2 and time.monotonic() < deadline:
            deliver_due(deliveries, settings, client)
            time.sleep(0.02)
        deliver_due(deliveries, settings, client)
    assert len(receiver.got) == 2
    record = deliveries.for_job(job_id)
    assert record is not None and record.state is DeliveryState.FAILED and record.attempts == 2


def test_a_silent_receiver_times_out_and_a_closed_port_fails_without_blocking(
    store: JobStore,
) -> None:
    deliveries = DeliveryStore(store.engine)
    with receiving(delay_s=2.0) as slow, httpx.Client(timeout=0.3) as client:
        slow_job = ended_job(store, slow.url)
        started = time.monotonic()
        deliver_due(deliveries, settings_for(slow.url, webhook_timeout_s=0.3), client)
        assert time.monotonic() - started < 1.5
    record = deliveries.for_job(slow_job)
    assert record is not None and record.state is DeliveryState.DUE
    assert record.last_error is not None and "no answer within" in record.last_error
    closed = slow.url  # the receiver has stopped: nothing listens there now
    with httpx.Client(timeout=1) as client:
        job_id = ended_job(store, closed.replace("/hook", "/other"))
        deliver_due(deliveries, settings_for(closed, webhook_retry_s=3600), client)
    record = deliveries.for_job(job_id)
    assert record is not None and record.last_error is not None
    assert record.last_error.startswith("could not connect to 127.0.0.1")


def test_a_host_taken_off_the_allow_list_is_never_called(store: JobStore) -> None:
    deliveries = DeliveryStore(store.engine)
    with receiving() as receiver, httpx.Client() as client:
        job_id = ended_job(store, receiver.url)
        deliver_due(deliveries, settings_for("http://hooks.example.org"), client)
    assert receiver.got == []
    record = deliveries.for_job(job_id)
    assert record is not None and record.state is DeliveryState.FAILED
    assert record.last_error is not None and "not among the hosts" in record.last_error


# -- a webhook that cannot be sent ---------------------------------------------------------


@pytest.mark.parametrize(
    ("stored", "why"),
    [
        ("http://localhost..:{port}/hook", "empty label"),
        ("http://localhost:{port}/tab\there", "control character or space"),
        ("http://localhost:{port}/x\u200by", "control character or space"),
    ],
)
def test_a_stored_url_the_sender_chokes_on_is_a_counted_failure_and_the_next_one_goes(
    store: JobStore, stored: str, why: str
) -> None:
    deliveries = DeliveryStore(store.engine)
    with receiving() as receiver, httpx.Client() as client:
        bad = ended_job(store, receiver.url)
        stored_as(store, bad, stored.format(port=receiver.port))
        good = ended_job(store, receiver.url + "?good")
        assert deliver_due(deliveries, settings_for(receiver.url), client) == 2
        (got,) = receiver.wait_for(1)
    assert got.path == "/hook?good"
    record = deliveries.for_job(bad)
    assert record is not None and record.state is DeliveryState.FAILED  # no try ever will
    assert record.attempts == 1 and record.last_error is not None
    assert record.last_error.startswith("not sent: ") and why in record.last_error
    sent = deliveries.for_job(good)
    assert sent is not None and sent.state is DeliveryState.DELIVERED


@pytest.mark.parametrize(
    ("fault", "why"),
    [
        (socket.gaierror(socket.EAI_NONAME, "Name or service not known"),
         "could not resolve localhost: [Errno -2] Name or service not known"),
        (UnicodeError("label empty or too long"),
         "could not resolve localhost: label empty or too long"),
        (RuntimeError("a bug"), "could not be sent: RuntimeError: a bug"),
    ],
)  # fmt: skip
def test_an_error_while_sending_is_a_failed_try_tried_again_after_a_backoff(
    store: JobStore, fault: Exception, why: str
) -> None:
    deliveries = DeliveryStore(store.engine)

    def broken(host: str, port: int) -> list[tuple[Any, ...]]:
        raise fault

    with receiving() as receiver, httpx.Client() as client:
        job_id = ended_job(store, receiver.url)
        settings = settings_for(receiver.url, webhook_retry_s=60)
        assert deliver_due(deliveries, settings, client, resolver=broken) == 1
    assert receiver.got == []
    record = deliveries.for_job(job_id)
    assert record is not None and record.state is DeliveryState.DUE
    assert record.attempts == 1 and record.last_error == why
    assert record.next_attempt_at is not None and record.next_attempt_at > utcnow()


def test_the_sender_thread_outlives_a_url_it_chokes_on(store: JobStore) -> None:
    deliveries = DeliveryStore(store.engine)
    stopped = threading.Event()
    with receiving() as receiver:
        bad = ended_job(store, receiver.url)
        stored_as(store, bad, f"http://localhost..:{receiver.port}/hook")
        ended_job(store, receiver.url + "?after")
        sender = threading.Thread(
            target=run_deliveries, args=(deliveries, settings_for(receiver.url), stopped)
        )
        sender.start()
        try:
            (got,) = receiver.wait_for(1, timeout_s=10)
            assert sender.is_alive()
        finally:
            stopped.set()
            sender.join(timeout=10)
    assert got.path == "/hook?after"
    record = deliveries.for_job(bad)
    assert record is not None and record.state is DeliveryState.FAILED and record.attempts == 1


def test_a_sender_thread_that_stops_anyway_is_started_again(
    store: JobStore, caplog: pytest.LogCaptureFixture
) -> None:
    deliveries = DeliveryStore(store.engine)
    settings = settings_for("http://localhost:9000")
    stopped = threading.Event()
    runs: list[str] = []

    def sender(database: DeliveryStore, given: Settings, until: threading.Event, **_: Any) -> None:
        runs.append(threading.current_thread().name)
        if len(runs) == 1:
            raise RuntimeError("a bug no try caught")
        until.wait()

    supervisor = threading.Thread(
        target=supervise_deliveries,
        args=(deliveries, settings, stopped),
        kwargs={"sender": sender, "restart_s": 0.05},
    )
    with caplog.at_level(logging.ERROR, logger="worker.deliveries"):
        supervisor.start()
        deadline = time.monotonic() + 10
        while len(runs) < 2 and time.monotonic() < deadline:
            time.sleep(0.01)
        stopped.set()
        supervisor.join(timeout=10)
    assert not supervisor.is_alive()
    assert runs == ["webhook-sender", "webhook-sender"]
    assert "the webhook sender stopped" in caplog.text and "a bug no try caught" in caplog.text


def test_a_sender_records_that_it_passed_on_its_worker_row(store: JobStore) -> None:
    deliveries = DeliveryStore(store.engine)
    assert deliveries.backlog().last_pass_at is None
    before = utcnow()
    store.worker_seen("host:1", started_at=before)
    stopped = threading.Event()
    sender = threading.Thread(
        target=run_deliveries,
        args=(deliveries, settings_for("http://localhost:9000"), stopped),
        kwargs={"owner": "host:1"},
    )
    sender.start()
    try:
        deadline = time.monotonic() + 10
        while deliveries.backlog().last_pass_at is None and time.monotonic() < deadline:
            time.sleep(0.05)
    finally:
        stopped.set()
        sender.join(timeout=10)
    passed = deliveries.backlog().last_pass_at
    assert passed is not None and before <= passed <= utcnow()


# -- which addresses, and the one the sender connects to -----------------------------------


@pytest.fixture
def loopback_2() -> Iterator[Receiver]:
    """A receiver on 127.0.0.2 at http://hooks.allowed.test:<port>/hook."""
    with receiving(bind="127.0.0.2", name=NAME) as receiver:
        yield receiver


def test_an_allowed_name_that_resolves_to_a_loopback_address_is_refused_until_it_is_allowed(
    store: JobStore, loopback_2: Receiver
) -> None:
    deliveries = DeliveryStore(store.engine)
    dns = Dns(["127.0.0.2"])
    job_id = ended_job(store, loopback_2.url)
    with httpx.Client() as client:
        # a retry waits longer than a pass takes, so each pass makes one try
        by_name = Settings(webhook_hosts=(NAME,), webhook_secret=SECRET, webhook_retry_s=0.5)
        assert deliver_due(deliveries, by_name, client, resolver=dns) == 1
        assert loopback_2.got == []
        record = deliveries.for_job(job_id)
        assert record is not None and record.state is DeliveryState.DUE and record.attempts == 1
        assert record.last_error == (
            f"not sent: {NAME} resolves to 127.0.0.2, a loopback address "
            "(NANONAV_WEBHOOK_ADDRESSES may allow it)"
        )
        time.sleep(0.6)
        allowed = Settings(**{**by_name.model_dump(), "webhook_addresses": "127.0.0.2"})
        assert deliver_due(deliveries, allowed, client, resolver=dns) == 1
        (got,) = loopback_2.wait_for(1)
    assert got.local_address == "127.0.0.2"
    assert got.headers["host"] == f"{NAME}:{loopback_2.port}"
    assert dns.asked == [(NAME, loopback_2.port)] * 2  # once per try, never by the connection
    record = deliveries.for_job(job_id)
    assert record is not None and record.state is DeliveryState.DELIVERED and record.attempts == 2


def test_every_address_a_name_resolves_to_must_be_allowed(
    store: JobStore, loopback_2: Receiver
) -> None:
    deliveries = DeliveryStore(store.engine)
    job_id = ended_job(store, loopback_2.url)
    settings = settings_for(loopback_2.url, webhook_addresses="127.0.0.2")
    with httpx.Client() as client:
        deliver_due(deliveries, settings, client, resolver=Dns(["127.0.0.2", "10.1.2.3"]))
    assert loopback_2.got == []
    record = deliveries.for_job(job_id)
    assert record is not None and record.last_error is not None
    assert "resolves to 10.1.2.3, a private address" in record.last_error


@pytest.mark.parametrize(
    "address", ["169.254.169.254", "::ffff:169.254.169.254", "fd00:ec2::254", "::ffff:127.0.0.2"]
)
def test_a_name_pointed_at_a_metadata_or_mapped_loopback_address_is_refused(
    store: JobStore, loopback_2: Receiver, address: str
) -> None:
    deliveries = DeliveryStore(store.engine)
    job_id = ended_job(store, loopback_2.url)
    settings = settings_for(loopback_2.url, webhook_addresses="")
    with httpx.Client() as client:
        deliver_due(deliveries, settings, client, resolver=Dns([address]))
    record = deliveries.for_job(job_id)
    assert record is not None and record.last_error is not None
    assert record.last_error.startswith(f"not sent: {NAME} resolves to {address}, a ")
    assert loopback_2.got == []


def test_an_address_in_the_url_is_checked_without_a_lookup(store: JobStore) -> None:
    deliveries = DeliveryStore(store.engine)
    dns = Dns([])
    with receiving(bind="127.0.0.2", name="127.0.0.2") as receiver, httpx.Client() as client:
        job_id = ended_job(store, receiver.url)
        deliver_due(deliveries, settings_for(receiver.url, webhook_addresses=""), client,
                    resolver=dns)  # fmt: skip
        record = deliveries.for_job(job_id)
        assert record is not None and record.last_error is not None
        assert "127.0.0.2 is a loopback address" in record.last_error
        later = ended_job(store, receiver.url)
        deliver_due(deliveries, settings_for(receiver.url), client, resolver=dns)
        (got,) = receiver.wait_for(1)
    assert dns.asked == [] and got.headers["host"] == f"127.0.0.2:{receiver.port}"
    record = deliveries.for_job(later)
    assert record is not None and record.state is DeliveryState.DELIVERED


def test_upper_case_a_zero_padded_port_and_an_at_sign_in_the_query_reach_the_receiver(
    store: JobStore, loopback_2: Receiver
) -> None:
    deliveries = DeliveryStore(store.engine)
    dns = Dns(["127.0.0.2"])
    written = f"http://HOOKS.Allowed.TEST:0{loopback_2.port}/hook?@127.0.0.2"
    job_id = ended_job(store, written)
    record = deliveries.for_job(job_id)
    assert record is not None
    assert record.url == f"http://{NAME}:{loopback_2.port}/hook?@127.0.0.2"
    settings = settings_for(loopback_2.url, webhook_addresses="127.0.0.2")
    with httpx.Client() as client:
        assert deliver_due(deliveries, settings, client, resolver=dns) == 1
        (got,) = loopback_2.wait_for(1)
    assert got.path == "/hook?@127.0.0.2" and got.local_address == "127.0.0.2"
    assert got.headers["host"] == f"{NAME}:{loopback_2.port}"
    assert dns.asked == [(NAME, loopback_2.port)]


def certificate(directory: Path, name: str) -> tuple[Path, Path]:
    """A self-signed certificate for ``name`` and its key, made by the openssl command."""
    if shutil.which("openssl") is None:
        if in_ci():
            pytest.fail("openssl must be installed in CI; .ci/run installs it")
        pytest.skip("the openssl command makes the test certificates (apt-get install openssl)")
    cert, key = directory / f"{name}.pem", directory / f"{name}.key"
    subprocess.run(
        ["openssl", "req", "-x509", "-newkey", "ec", "-pkeyopt", "ec_paramgen_curve:prime256v1",
         "-nodes", "-days", "1", "-subj", f"/CN={name}", "-addext", f"subjectAltName=DNS:{name}",
         "-keyout", str(key), "-out", str(cert)],
        check=True, capture_output=True,
    )  # fmt: skip
    return cert, key


def test_https_goes_to_the_checked_address_with_the_name_for_sni_and_the_certificate(
    store: JobStore, tmp_path: Path
) -> None:
    deliveries = DeliveryStore(store.engine)
    cert, key = certificate(tmp_path, NAME)
    other, other_key = certificate(tmp_path, "other.allowed.test")
    trusted = ssl.create_default_context(cafile=str(cert))
    trusted.load_verify_locations(cafile=str(other))
    for served, served_key, delivered in ((cert, key, True), (other, other_key, False)):
        tls = ssl.SSLContext(ssl.PROTOCOL_TLS_SERVER)
        tls.load_cert_chain(served, served_key)
        with (
            receiving(bind="127.0.0.2", name=NAME, tls=tls) as receiver,
            httpx.Client(verify=trusted) as client,
        ):
            job_id = ended_job(store, receiver.url)
            settings = settings_for(receiver.url, webhook_addresses="127.0.0.2")
            deliver_due(deliveries, settings, client, resolver=Dns(["127.0.0.2"]))
            record = deliveries.for_job(job_id)
            assert record is not None
            assert receiver.server_names == [NAME]
            if delivered:
                (got,) = receiver.wait_for(1)
                assert got.local_address == "127.0.0.2"
                assert got.headers["host"] == f"{NAME}:{receiver.port}"
                assert record.state is DeliveryState.DELIVERED
            else:  # a certificate for another name, though the address is the right one
                assert receiver.got == [] and record.last_error is not None
                assert "CERTIFICATE_VERIFY_FAILED" in record.last_error
