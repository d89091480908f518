"""What every subcommand shares: exit codes, the usage error, and reading a JSON file."""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any, TypeAlias

from pydantic import ValidationError

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


def validation_messages(error: ValidationError) -> list[str]:
    """One line per error, naming the field by its dotted path (``robots.count: ...``)."""
    lines = []
    for item in error.errors(include_url=False):
        where = ".".join(str(part) for part in item["loc"]) or "scenario"
        lines.append(f"{where}: {item['msg']}")
    return lines
