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
    ],
)
def test_a_bad_value_fails_at_start_up(
    monkeypatch: pytest.MonkeyPatch, name: str, value: str
) -> None:
    monkeypatch.delenv("NANONAV_DATABASE_URL", raising=False)
    monkeypatch.setenv(name, value)
    with pytest.raises(ValidationError):
        Settings()
