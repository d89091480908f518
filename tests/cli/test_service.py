"""``nanonav migrate``, ``api`` and ``worker`` say in one line what is wrong with their
database or their settings, never with a traceback."""

from __future__ import annotations

import pytest

from nanonav.cli import main
from tests.processes import free_port


@pytest.fixture(autouse=True)
def no_settings(monkeypatch: pytest.MonkeyPatch) -> None:
    for name in ("DATABASE_URL", "NANONAV_DATABASE_URL", "NANONAV_WEBHOOK_HOSTS",
                 "NANONAV_WEBHOOK_SECRET", "NANONAV_PORT", "PORT"):  # fmt: skip
        monkeypatch.delenv(name, raising=False)


def test_a_database_that_does_not_answer_is_one_line(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    port = free_port()  # nothing listens there
    monkeypatch.setenv("DATABASE_URL", f"postgresql://postgres@127.0.0.1:{port}/nanonav")
    assert main(["migrate"]) == 1
    out, err = capsys.readouterr()
    assert out == ""
    assert err.startswith(
        f"nanonav migrate: cannot migrate postgresql+psycopg://postgres@127.0.0.1:{port}/nanonav: "
    )
    assert err.count("\n") == 1 and "Connection refused" in err and "Traceback" not in err


def test_a_settings_error_names_its_variable_in_the_users_words(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.setenv("NANONAV_WEBHOOK_HOSTS", "hooks.example.org")
    assert main(["migrate"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("nanonav migrate: settings: NANONAV_WEBHOOK_HOSTS is set but ")
    assert "Value error" not in err and "scenario" not in err
    monkeypatch.delenv("NANONAV_WEBHOOK_HOSTS")
    monkeypatch.setenv("NANONAV_PORT", "eighty")
    assert main(["api"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("nanonav api: NANONAV_PORT: "), err
    assert err.count("\n") == 1
