"""Signing and checking webhooks, and which callback URLs a server may call."""

from __future__ import annotations

import hashlib
import hmac
from ipaddress import ip_network

import pytest

from nanonav.webhooks import (
    SignatureMismatch,
    address_refusal,
    normalised,
    refusal,
    retry_delay_s,
    signature,
    verify,
)

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


@pytest.mark.parametrize(
    ("url", "why"),
    [
        ("http://localhost..:9000/x", "empty label"),
        ("http://.localhost:9000/x", "empty label"),
        ("http://localhost:9000/tab\there", "control character or space"),
        ("http://localhost:9000/x\ny", "control character or space"),
        ("http://localhost:9000/x y", "control character or space"),
        ("http://local\thost:9000/x", "control character or space"),
        ("http://localhost:9000/x\x7f", "control character or space"),
        ("http://localhost:9000/x\u00a0", "control character or space"),
        ("http://localhost:9000/x\u200b", "control character or space"),
        (" http://localhost:9000/x", "control character or space"),
        ("http://xn--:9000/x", "not a DNS name"),
        ("http://b\u00fccher\u2029.localhost:9000/x", "control character or space"),
        ("http://\u2603.localhost:9000/x", "not a URL"),
        ("http://" + "a" * 64 + ".localhost:9000/x", "longer than 63"),
        ("http://local%68ost:9000/x", "not a DNS name"),
        ("http://local!host:9000/x", "not a DNS name"),
        ("http://localhost:0/x", "not a port"),
        ("http://localhost:65536/x", "not a port"),
    ],
)
def test_a_url_the_sender_could_not_send_is_refused_by_the_check(url: str, why: str) -> None:
    hosts = ("localhost:9000", "*.localhost", "xn--", "local%68ost", "local!host")
    refused = refusal(url, hosts)
    assert refused is not None and why in refused, refused


@pytest.mark.parametrize(
    ("url", "sent"),
    [
        ("http://HOOKS.Example.ORG:09000/x", "http://hooks.example.org:9000/x"),
        (
            "http://hooks.example.org:9000/x?@127.0.0.2",
            "http://hooks.example.org:9000/x?@127.0.0.2",
        ),
        ("https://hooks.example.org:443/a/../b?q=1", "https://hooks.example.org/b?q=1"),
        ("http://b\u00fccher.example.org/\u00fc", "http://xn--bcher-kva.example.org/%C3%BC"),
        ("http://hooks.example.org./x", "http://hooks.example.org./x"),
    ],
)
def test_an_allowed_url_is_kept_in_the_form_the_sender_sends(url: str, sent: str) -> None:
    hosts = ("hooks.example.org", "*.example.org")
    assert refusal(url, hosts) is None
    assert normalised(url) == sent
    assert normalised(sent) == sent
    assert refusal(sent, hosts) is None


def test_a_url_that_grows_past_the_limit_when_normalised_is_refused() -> None:
    url = "https://hooks.example.org/" + "\u00fc" * 1000  # 6 bytes each once percent-encoded
    assert len(url) < 2048
    assert "longer than 2048" in str(refusal(url, ("hooks.example.org",)))


@pytest.mark.parametrize(
    ("address", "why"),
    [
        ("127.0.0.2", "a loopback address"),
        ("::1", "a loopback address"),
        ("::ffff:127.0.0.1", "a loopback address"),
        ("10.1.2.3", "a private address"),
        ("172.16.0.1", "a private address"),
        ("192.168.1.1", "a private address"),
        ("::ffff:192.168.1.1", "a private address"),
        ("fd12::1", "a private address"),
        ("169.254.169.254", "a cloud metadata address"),
        ("::ffff:169.254.169.254", "a cloud metadata address"),
        ("fd00:ec2::254", "a cloud metadata address"),
        ("100.100.100.200", "a cloud metadata address"),
        ("169.254.1.1", "a link-local address"),
        ("fe80::1", "a link-local address"),
        ("0.0.0.0", "the unspecified address"),
        ("::", "the unspecified address"),
        ("224.0.0.1", "a multicast address"),
        ("ff02::1", "a multicast address"),
        ("240.0.0.1", "a reserved address"),
        ("255.255.255.255", "a reserved address"),
        ("100.64.0.1", "not a public address"),
        ("2002:7f00:1::", "a loopback address"),  # 6to4 of 127.0.0.1
        ("64:ff9b::a01:203", "a private address"),  # NAT64 of 10.1.2.3
        ("fec0::1", "a site-local address"),  # deprecated (RFC 3879), never public
        ("feff:ffff::1", "a site-local address"),
        ("::10.1.2.3", "a private address"),  # IPv4-compatible
    ],
)
def test_an_address_that_is_not_public_is_refused_saying_what_it_is(address: str, why: str) -> None:
    refused = address_refusal(address, ())
    assert refused is not None and why in refused and "NANONAV_WEBHOOK_ADDRESSES" in refused


@pytest.mark.parametrize(
    "address", ["93.184.215.14", "2606:4700::1111", "64:ff9b::808:808", "2002:808:808::1"]
)
def test_a_public_address_may_be_called(address: str) -> None:
    assert address_refusal(address, ()) is None


def test_allowed_networks_open_their_addresses_but_a_metadata_address_only_by_itself() -> None:
    allowed = (ip_network("127.0.0.0/8"), ip_network("10.1.2.3"), ip_network("169.254.0.0/16"))
    assert address_refusal("127.0.0.2", allowed) is None
    assert address_refusal("::ffff:127.0.0.2", allowed) is None
    assert address_refusal("10.1.2.3", allowed) is None
    assert "a private address" in str(address_refusal("10.1.2.4", allowed))
    assert "a loopback address" in str(address_refusal("::1", allowed))
    assert address_refusal("169.254.1.1", allowed) is None
    assert "a cloud metadata address" in str(address_refusal("169.254.169.254", allowed))
    assert address_refusal("169.254.169.254", (ip_network("169.254.169.254/32"),)) is None


def test_no_allowed_hosts_means_no_webhooks() -> None:
    assert "sends no webhooks" in str(refusal("https://hooks.example.org/", ()))


def test_retries_wait_twice_as_long_each_time_up_to_an_hour() -> None:
    assert [retry_delay_s(n, 10.0) for n in (1, 2, 3, 4)] == [10.0, 20.0, 40.0, 80.0]
    assert retry_delay_s(30, 10.0) == 3600.0


# Every IPv6 form of 169.254.169.254: each carries it in its low 32 bits, but 6to4 (in bits
# 16-47) and Teredo (its server in bits 32-63, its client inverted in the low 32 bits).
METADATA_FORMS = [
    "::ffff:169.254.169.254",  # IPv4-mapped
    "::169.254.169.254",  # IPv4-compatible, written as ::a9fe:a9fe too
    "::ffff:0:169.254.169.254",  # IPv4-translated (RFC 2765)
    "64:ff9b::169.254.169.254",  # NAT64
    "2002:a9fe:a9fe::",  # 6to4
    "2002:a9fe:a9fe:1:2:3:4:5",
    "2001:0:a9fe:a9fe:8000:63bf:3fff:fdd2",  # Teredo, the metadata address as its server
    "2001:0:4136:e378:8000:63bf:5601:5601",  # Teredo, the metadata address as its client
]


@pytest.mark.parametrize("address", METADATA_FORMS)
def test_no_network_however_wide_opens_an_ipv6_form_of_a_metadata_address(address: str) -> None:
    everything = (ip_network("::/0"), ip_network("0.0.0.0/0"))
    for allowed in ((), (ip_network("::/0"),), everything):
        refused = address_refusal(address, allowed)
        assert refused is not None and "a cloud metadata address" in refused, allowed
    listed = (*everything, ip_network("169.254.169.254/32"))
    assert address_refusal(address, listed) is None


def test_an_ipv6_network_does_not_open_the_ipv4_addresses_its_addresses_carry() -> None:
    ipv6 = (ip_network("::/0"),)
    assert address_refusal("fd12::1", ipv6) is None
    assert address_refusal("2001:0:4136:e378:8000:63bf:f7f7:f7f7", ipv6) is None  # Teredo, 8.8.8.8
    for carried, why in (
        ("2002:7f00:1::", "a loopback address"),
        ("2002:a01:203::", "a private address"),
        ("::ffff:10.1.2.3", "a private address"),
        ("::10.1.2.3", "a private address"),
        ("64:ff9b::a01:203", "a private address"),
        ("2001:0:a01:203:8000:63bf:f7f7:f7f7", "a private address"),  # Teredo server
        ("2001:0:4136:e378:8000:63bf:f5fe:fdfc", "a private address"),  # Teredo client 10.1.2.3
    ):
        assert why in str(address_refusal(carried, ipv6)), carried
        with_ipv4 = (*ipv6, ip_network("10.0.0.0/8"), ip_network("127.0.0.0/8"))
        assert address_refusal(carried, with_ipv4) is None, carried


def test_allowed_networks_open_site_local_addresses_and_the_ipv6_loopback_as_any_other() -> None:
    assert address_refusal("fec0::1", (ip_network("fec0::/10"),)) is None
    assert address_refusal("::1", (ip_network("::1/128"),)) is None  # not IPv4-compatible 0.0.0.1
