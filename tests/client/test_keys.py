"""The client and the command with an API that has keys: the key goes in the Bearer header,
from the argument, ``--api-key`` or ``$NANONAV_API_KEY``, and is never printed."""

from __future__ import annotations

from collections.abc import Iterator

import httpx
import pytest

from nanonav.cli import main
from nanonav.client import ApiError, Client
from nanonav.settings import Settings
from nanonav.store.migrate import upgrade
from service.app import create_app
from tests.conftest import serve
from tests.service.test_security import KEY_A, KEY_B

WRONG = "mallory-0Zx9Cv8Bn7Mq6Wr5Et4Yu3Io2Pa1Sd"


@pytest.fixture
def keyed_url(sqlite_url: str) -> Iterator[str]:
    upgrade(sqlite_url)
    with serve(create_app(Settings(database_url=sqlite_url, api_keys=f"{KEY_A},{KEY_B}"))) as url:
        yield url


def test_the_client_sends_its_key_and_sees_only_its_own_jobs(keyed_url: str) -> None:
    with Client(keyed_url, api_key=KEY_A) as alice, Client(keyed_url, api_key=KEY_B) as bruno:
        job = alice.submit({})
        assert [j.id for j in alice.jobs()] == [job.id]
        assert list(bruno.jobs()) == []
        with pytest.raises(ApiError) as missing:
            bruno.job(job.id)
        assert missing.value.status == 404
        assert alice.cancel(job.id).status == "cancelled"  # a body-less POST goes through


def test_a_missing_or_wrong_key_is_a_401_whose_message_never_shows_the_key(
    keyed_url: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    with Client(keyed_url) as anonymous, pytest.raises(ApiError) as refused:
        list(anonymous.jobs())
    assert refused.value.status == 401
    monkeypatch.setenv("NANONAV_API_KEY", WRONG)
    with Client(keyed_url) as wrong, pytest.raises(ApiError) as refused:
        wrong.submit({})
    assert refused.value.status == 401 and WRONG not in str(refused.value)
    monkeypatch.setenv("NANONAV_API_KEY", KEY_A)
    with Client(keyed_url) as from_environment:
        assert from_environment.submit({}).status == "queued"


def test_the_key_goes_in_the_bearer_header_of_every_request() -> None:
    seen: list[httpx.Request] = []

    def answer(request: httpx.Request) -> httpx.Response:
        seen.append(request)
        return httpx.Response(200, json={"jobs": [], "next_cursor": None, "next": None})

    with Client("http://api.test", api_key=KEY_A, transport=httpx.MockTransport(answer)) as api:
        list(api.jobs())
    assert seen[0].headers["authorization"] == f"Bearer {KEY_A}"
    assert seen[0].headers["x-requested-with"] == "nanonav-client"


def test_the_command_takes_the_key_from_its_option_or_the_environment_and_never_prints_it(
    keyed_url: str, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    assert main(["submit", "--preset", "paper-single", "--url", keyed_url, "--api-key", KEY_A]) == 0
    out, err = capsys.readouterr()
    assert out.startswith("job ") and KEY_A not in out + err
    assert main(["jobs", "--url", keyed_url, "--api-key", WRONG]) == 2
    out, err = capsys.readouterr()
    assert "401" in err or "key" in err
    assert WRONG not in out + err
    monkeypatch.setenv("NANONAV_API_KEY", KEY_A)
    assert main(["jobs", "--url", keyed_url]) == 0
    out, err = capsys.readouterr()
    assert "queued" in out and KEY_A not in out + err
