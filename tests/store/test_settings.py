from __future__ import annotations

import pytest
from pydantic import ValidationError

from nanonav.settings import DEFAULT_DATABASE_URL, Settings


def test_defaults(monkeypatch: pytest.MonkeyPatch) -> None:
    for name in ("DATABASE_URL", "NANONAV_DATABASE_URL", "HOST", "PORT", "NANONAV_PORT"):
        monkeypatch.delenv(name, raising=False)
    settings = Settings()
    assert settings.database_url == DEFAULT_DATABASE_URL
    assert (settings.host, settings.port) == ("127.0.0.1", 8000)
    assert settings.robot_steps_budget == 1_000_000_000


def test_database_url_is_read_with_and_without_the_prefix(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("NANONAV_DATABASE_URL", raising=False)
    monkeypatch.setenv("DATABASE_URL", "postgresql://u:p@db:5432/nanonav")
    assert Settings().database_url == "postgresql+psycopg://u:p@db:5432/nanonav"
    monkeypatch.setenv("NANONAV_DATABASE_URL", "sqlite:///elsewhere.db")
    assert Settings().database_url == "sqlite:///elsewhere.db"


def test_prefixed_limits_and_port(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("NANONAV_ROBOT_STEPS_BUDGET", "5000")
    monkeypatch.setenv("PORT", "9001")
    settings = Settings()
    assert settings.robot_steps_budget == 5000
    assert settings.port == 9001


@pytest.mark.parametrize(
    ("name", "value"),
    [
        ("DATABASE_URL", "mysql://x"),
        ("DATABASE_URL", "not a url"),
        ("NANONAV_PORT", "70000"),
        ("NANONAV_ROBOT_STEPS_BUDGET", "0"),
        ("NANONAV_JOB_TIME_LIMIT_S", "-1"),
        ("NANONAV_RETENTION_DAYS", "0"),
        ("NANONAV_RETENTION_DAYS", "-3"),
        ("NANONAV_RETENTION_DAYS", "inf"),
        ("NANONAV_RETENTION_DAYS", "a week"),
    ],
)
def test_a_bad_value_fails_at_start_up(
    monkeypatch: pytest.MonkeyPatch, name: str, value: str
) -> None:
    monkeypatch.delenv("NANONAV_DATABASE_URL", raising=False)
    monkeypatch.setenv(name, value)
    with pytest.raises(ValidationError):
        Settings()


def test_retention_is_off_unless_set_in_days(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("NANONAV_RETENTION_DAYS", raising=False)
    assert Settings().retention_days is None
    monkeypatch.setenv("NANONAV_RETENTION_DAYS", "0.5")
    assert Settings().retention_days == 0.5


WEBHOOK_SECRET = "kq3N9vTz0bX7mR2sW5yC8dF1gH4jL6pA"


def test_webhook_hosts_are_read_comma_separated_with_their_secret(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.setenv(
        "NANONAV_WEBHOOK_HOSTS", " Hooks.Example.org, *.lab.example.net,localhost:9000 "
    )
    monkeypatch.setenv("NANONAV_WEBHOOK_SECRET", WEBHOOK_SECRET)
    settings = Settings()
    assert settings.webhook_hosts == ("hooks.example.org", "*.lab.example.net", "localhost:9000")
    assert settings.webhook_secret is not None
    assert settings.webhook_secret.get_secret_value() == WEBHOOK_SECRET
    assert WEBHOOK_SECRET not in repr(settings)
    assert Settings(**settings.model_dump()).webhook_secret == settings.webhook_secret


@pytest.mark.parametrize(
    ("hosts", "secret", "why"),
    [
        ("hooks.example.org", None, "NANONAV_WEBHOOK_SECRET is not"),
        ("hooks.example.org", "k3Q9zP", "shorter than 32"),
        ("hooks.example.org", "changeme-changeme-changeme-changeme", "placeholder"),
        ("hooks.example.org", "a" * 40, "placeholder"),
        ("https://hooks.example.org/x", WEBHOOK_SECRET, "a webhook host looks like"),
        ("hooks.*.org", WEBHOOK_SECRET, "a webhook host looks like"),
        ("localhost:0", WEBHOOK_SECRET, "not a port"),
        ("localhost:\u0661", WEBHOOK_SECRET, "not a port"),
        ("localhost:\u00b2", WEBHOOK_SECRET, "not a port"),
    ],
)
def test_bad_webhook_settings_stop_the_process_saying_why_without_the_secret(
    monkeypatch: pytest.MonkeyPatch, hosts: str, secret: str | None, why: str
) -> None:
    monkeypatch.setenv("NANONAV_WEBHOOK_HOSTS", hosts)
    if secret is not None:
        monkeypatch.setenv("NANONAV_WEBHOOK_SECRET", secret)
    with pytest.raises(ValidationError, match=why) as refused:
        Settings()
    if secret is not None:
        assert secret not in str(refused.value)


def test_webhook_addresses_are_read_as_networks_and_default_to_none(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.delenv("NANONAV_WEBHOOK_ADDRESSES", raising=False)
    assert Settings().webhook_addresses == ()
    monkeypatch.setenv("NANONAV_WEBHOOK_ADDRESSES", " 127.0.0.0/8, 10.1.2.3,::1,fd00::/8 ")
    settings = Settings()
    assert [str(network) for network in settings.webhook_addresses] == [
        "127.0.0.0/8", "10.1.2.3/32", "::1/128", "fd00::/8"
    ]  # fmt: skip
    assert Settings(**settings.model_dump()).webhook_addresses == settings.webhook_addresses


@pytest.mark.parametrize(
    ("addresses", "why"),
    [
        ("localhost", "'localhost' is not an address or a network"),
        ("10.0.0.300", "is not an address or a network"),
        ("10.0.0.1/8", "has host bits set: did you mean 10.0.0.0/8"),
        ("127.0.0.0/8,hooks.example.org", "'hooks.example.org' is not an address"),
    ],
)
def test_bad_webhook_addresses_stop_the_process_saying_which(
    monkeypatch: pytest.MonkeyPatch, addresses: str, why: str
) -> None:
    monkeypatch.setenv("NANONAV_WEBHOOK_ADDRESSES", addresses)
    with pytest.raises(ValidationError, match=why):
        Settings()


def test_every_setting_is_read_from_its_prefixed_variable(monkeypatch: pytest.MonkeyPatch) -> None:
    """Each field is read from NANONAV_<NAME> (the prefix alone names it; DATABASE_URL, HOST
    and PORT are also read without it): a number or a switch given as nonsense there is
    refused, naming the field, so the variable was read."""
    from pydantic import ValidationError

    from nanonav.settings import Settings

    checked = 0
    for name in Settings.model_fields:
        value = getattr(Settings(), name)
        if isinstance(value, str) or not isinstance(value, (bool, int, float)):
            continue
        with monkeypatch.context() as patched:
            patched.setenv(f"NANONAV_{name.upper()}", "not a value")
            with pytest.raises(ValidationError) as refused:
                Settings()
            assert any(name in str(error["loc"]) or name.upper() in str(error["loc"])
                       for error in refused.value.errors()), name  # fmt: skip
        checked += 1
    assert checked > 30
