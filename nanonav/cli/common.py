"""What every subcommand shares: exit codes, the usage error, reading a JSON file, and for those
that talk to a running API, their options and their client."""

from __future__ import annotations

import argparse
import json
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any, TypeAlias

from pydantic import ValidationError

from nanonav.client import Client

EXIT_OK = 0
EXIT_FAILED = 1  # the work failed, or a server could not be reached or failed
EXIT_USAGE = 2  # input the user can fix, here or as the server judged it (a 4xx answer)
EXIT_INTERRUPTED = 130
# The reader of the output left before it ended (a closed pipe), as 128 + SIGPIPE says in a shell.
EXIT_PIPE_CLOSED = 141

# Quoted: argparse's class cannot be subscripted at run time.
Subcommands: TypeAlias = "argparse._SubParsersAction[argparse.ArgumentParser]"


class UsageError(Exception):
    """Input the user can fix: one message per line, printed to stderr with exit code 2."""

    def __init__(self, lines: list[str]) -> None:
        super().__init__("\n".join(lines))
        self.lines = lines


class Failed(Exception):
    """Work that ran and did not succeed (a failed or cancelled job): exit code 1."""

    def __init__(self, lines: list[str]) -> None:
        super().__init__("\n".join(lines))
        self.lines = lines


def read_json_object(path: Path, what: str) -> dict[str, Any]:
    """The JSON object in ``path``; a file that is missing, unreadable or not an object is a
    ``UsageError`` in one line."""
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as error:
        raise UsageError([f"cannot read {path}: {error}"]) from error
    try:
        loaded = json.loads(text)
    except json.JSONDecodeError as error:
        raise UsageError(
            [f"{path}: invalid JSON at line {error.lineno} column {error.colno}: {error.msg}"]
        ) from error
    if not isinstance(loaded, dict):
        raise UsageError([f"{path}: the {what} must be a JSON object"])
    return loaded


# pydantic's words before a validator's own message, which say nothing to a user
PYDANTIC_PREFIXES = ("Value error, ", "Assertion failed, ")


def validation_messages(error: ValidationError) -> list[str]:
    """One line per error, naming the field by its dotted path (``robots.count: ...``)."""
    lines = []
    for item in error.errors(include_url=False):
        where = ".".join(str(part) for part in item["loc"]) or "scenario"
        lines.append(f"{where}: {_message(item['msg'])}")
    return lines


def settings_messages(error: ValidationError) -> list[str]:
    """One line per error in the settings, naming each by its environment variable
    (``NANONAV_PORT: ...``); one about several is the settings'."""
    lines = []
    for item in error.errors(include_url=False):
        names = [str(part) for part in item["loc"]]
        if not names:
            lines.append(f"settings: {_message(item['msg'])}")
            continue
        first = names[0].upper()
        variable = first if first.startswith("NANONAV_") else f"NANONAV_{first}"
        where = ".".join([variable, *names[1:]])
        lines.append(f"{where}: {_message(item['msg'])}")
    return lines


def _message(text: str) -> str:
    for prefix in PYDANTIC_PREFIXES:
        if text.startswith(prefix):
            return text.removeprefix(prefix)
    return text


URL_HELP = "the API's base URL (default: $NANONAV_URL, else http://127.0.0.1:8000)"
KEY_HELP = (
    "the API key, for a server with keys (default: $NANONAV_API_KEY, which keeps it out of the "
    "process list)"
)


def _url(text: str) -> str:
    if not text.startswith(("http://", "https://")):
        raise argparse.ArgumentTypeError(f"not an http:// or https:// URL: {text!r}")
    return text


def positive(text: str) -> int:
    """An id or a count given on the command line: a whole number of at least 1."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a whole number: {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be at least 1, not {value}")
    return value


def add_url(parser: argparse.ArgumentParser) -> None:
    """The options of every command that talks to a running API: where, and with which key."""
    parser.add_argument("--url", type=_url, help=URL_HELP)
    parser.add_argument("--api-key", metavar="KEY", help=KEY_HELP)


@contextmanager
def connect(args: argparse.Namespace) -> Iterator[Client]:
    """A client for ``add_url``'s options; a URL or key the client refuses is a UsageError."""
    try:
        client = Client(args.url, api_key=args.api_key)
    except ValidationError as error:
        raise UsageError(validation_messages(error)) from error
    with client:
        yield client


def parse_setting(text: str) -> tuple[list[str], Any]:
    """``FIELD=VALUE`` as the field's path and its value: JSON (20, true, null, [1, 2]) where
    it reads as JSON, else the text itself (gradient)."""
    field, equals, value = text.partition("=")
    path = field.strip().split(".")
    if not equals or not all(path):
        raise argparse.ArgumentTypeError(f"not FIELD=VALUE: {text!r}")
    try:
        return path, json.loads(value)
    except ValueError:
        return path, value


def add_set_option(parser: argparse.ArgumentParser, over: str) -> None:
    """``--set FIELD=VALUE`` (repeatable) into ``args.settings``, over ``over``'s fields."""
    parser.add_argument(
        "--set", action="append", default=[], type=parse_setting, metavar="FIELD=VALUE",
        dest="settings",
        help=f"a scenario field by its dotted name, over {over} (repeatable): "
        "learning.episodes=20, robots.policy=gradient; VALUE is read as JSON, else as text",
    )  # fmt: skip


def with_settings(scenario: dict[str, Any], settings: list[tuple[list[str], Any]]) -> None:
    """``scenario`` with each ``--set`` path set to its value, the sections on the way made as
    needed."""
    for path, value in settings:
        section = scenario
        for i, name in enumerate(path[:-1]):
            inner = section.setdefault(name, {})
            if not isinstance(inner, dict):
                where = ".".join(path[: i + 1])
                raise UsageError([f"--set {'.'.join(path)}: {where} is not a section"])
            section = inner
        section[path[-1]] = value
