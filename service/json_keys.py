"""JSON bodies that give a key twice in one object are refused (400 ``duplicate-key``, naming
where), rather than read as JSON parsers do, the last one winning: ``{"seed": 1, "seed": 2}``
more likely says a mistake than seed 2."""

from __future__ import annotations

import json
from typing import Any

from fastapi import Request

from service.problems import ProblemError, field_error

DUPLICATE_RULE = "duplicate_key"
Path = tuple[str | int, ...]


class DuplicateKey(ProblemError):
    status = 400
    slug = "duplicate-key"
    title = "Duplicate key"


class _Repeated(dict[str, Any]):
    """An object of the body that gives ``key`` more than once."""

    def __init__(self, pairs: list[tuple[str, Any]], key: str) -> None:
        super().__init__(pairs)
        self.key = key


def _object(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    seen: set[str] = set()
    for key, _ in pairs:
        if key in seen:
            return _Repeated(pairs, key)
        seen.add(key)
    return dict(pairs)


def repeated_key(text: bytes) -> Path | None:
    """Where the first key given twice in one object of the JSON ``text`` is (the object's path,
    then the key), in document order; None when none is, or when ``text`` is no JSON."""
    try:
        value = json.loads(text, object_pairs_hook=_object)
    except (ValueError, RecursionError):
        return None  # not JSON, or nested past the parser's depth: the route refuses it as such
    pending: list[tuple[Path, Any]] = [((), value)]
    while pending:
        path, item = pending.pop()
        if isinstance(item, _Repeated):
            return (*path, item.key)
        if isinstance(item, dict):
            pending.extend(((*path, k), v) for k, v in reversed(item.items()))
        elif isinstance(item, list):
            pending.extend(((*path, i), v) for i, v in reversed(list(enumerate(item))))
    return None


async def refuse_duplicate_keys(request: Request) -> None:
    """400 ``duplicate-key`` at the first key the JSON body gives twice in one object."""
    body = await request.body()
    found = repeated_key(body) if body else None
    if found is not None:
        error = field_error(
            ("body", *found), f"the key {found[-1]!r} is given twice in the same object",
            DUPLICATE_RULE,
        )  # fmt: skip
        raise DuplicateKey(f"{error.pointer}: {error.detail}", [error])
