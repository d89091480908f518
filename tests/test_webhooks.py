"""Signing and checking webhooks, and which callback URLs a server may call."""

from __future__ import annotations

import hashlib
import hmac

import pytest

from nanonav.webhooks import SignatureMismatch, refusal, retry_delay_s, signature, verify

SECRET = "kq3N9vTz0bX7mR2sW5yC8dF1gH4jL6pA"


def test_the_signature_is_hmac_sha256_of_the_timestamp_and_the_body() -> None:
    header = signature(SECRET, b'{"a":1}', 1_700_000_000)
    expected = hmac.new(SECRET.encode(), b'1700000000.{"a":1}', hashlib.sha256).hexdigest()
    assert header == f"t=1700000000,v1={expected}"
    assert verify(SECRET, header, b'{"a":1}', now=1_700_000_010) == 1_700_000_000


@pytest.mark.parametrize(
    ("header", "body", "now", "why"),
    [
        (None, b"{}", 100, "no NanoNav-Signature"),
        ("v1=abc", b"{}", 100, "not a NanoNav-Signature"),
        ("t=x,v1=abc", b"{}", 100, "not a NanoNav-Signature"),
        (signature(SECRET, b"{}", 100), b"{ }", 100, "does not match"),
        (signature("another-secret-another-secret-xx", b"{}", 100), b"{}", 100, "does not match"),
        (signature(SECRET, b"{}", 100), b"{}", 401, "over 300 s away"),
    ],
)
def test_verify_refuses_a_missing_tampered_foreign_or_stale_signature(
    header: str | None, body: bytes, now: float, why: str
) -> None:
    with pytest.raises(SignatureMismatch, match=why):
        verify(SECRET, header, body, now=now)


@pytest.mark.parametrize(
    ("url", "allowed"),
    [
        ("https://hooks.example.org/x", True),
        ("http://HOOKS.example.org./x?job=1", True),
        ("https://a.b.lab.example.net/hook", True),
        ("https://lab.example.net/hook", False),  # *.example.net is its subdomains only
        ("http://localhost:9000/hook", True),
        ("http://localhost:9001/hook", False),  # localhost:9000 allows that port only
        ("https://evil.example.org.attacker.com/", False),
        ("https://attacker.com/?https://hooks.example.org", False),
        ("ftp://hooks.example.org/x", False),
        ("https://user:pw@hooks.example.org/x", False),
        ("https://hooks.example.org/x#frag", False),
        ("https:///nohost", False),
        ("http://localhost:99999/hook", False),
        ("not a url", False),
    ],
)
def test_only_urls_on_allowed_hosts_may_be_called(url: str, allowed: bool) -> None:
    hosts = ("hooks.example.org", "*.lab.example.net", "localhost:9000")
    assert (refusal(url, hosts) is None) is allowed


def test_no_allowed_hosts_means_no_webhooks() -> None:
    assert "sends no webhooks" in str(refusal("https://hooks.example.org/", ()))


def test_retries_wait_twice_as_long_each_time_up_to_an_hour() -> None:
    assert [retry_delay_s(n, 10.0) for n in (1, 2, 3, 4)] == [10.0, 20.0, 40.0, 80.0]
    assert retry_delay_s(30, 10.0) == 3600.0
