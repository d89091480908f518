"""Text a request may store: kept alike by SQLite and PostgreSQL, or refused by both.

PostgreSQL keeps no U+0000 (NUL) in a text column, nor anywhere in a JSON document (a key or a
value); SQLite keeps it. So a request that may store text (``JsonBody``'s routes) is refused with
422 ``nul_character`` when a string holds NUL anywhere in it: its JSON body (a key or a value, at
any depth), a query parameter (``callback_url``) or the Idempotency-Key header. The check comes
before the route reads anything, so both stores answer it alike. Any other character is
kept as sent. Query parameters of the routes that only read are typed (ids, states, cursors,
formats) and never reach a query as text.
"""

from __future__ import annotations

from typing import Any

from fastapi import Request

from service.problems import FieldError, InvalidInput, field_error

NUL = "\x00"
NUL_RULE = "nul_character"
# How NUL is written in a JSON text: it cannot be there raw (json.loads refuses a control
# character in a string). A body with neither this escape nor a zero byte (which UTF-16 and
# UTF-32, that json.loads also reads, are full of) holds none.
ESCAPED_NUL = b"\\u0000"

Path = tuple[str | int, ...]


def nul_in(value: Any) -> tuple[Path, bool] | None:
    """Where the first string holding NUL is in ``value``, parsed JSON: its path, and whether it
    is a key (the path then ends with it) rather than a value. None when there is none."""
    pending: list[tuple[Path, Any]] = [((), value)]
    while pending:
        path, item = pending.pop()
        if isinstance(item, str):
            if NUL in item:
                return path, False
        elif isinstance(item, dict):
            for key in item:
                if NUL in key:
                    return (*path, key), True
            pending.extend(((*path, k), v) for k, v in reversed(item.items()))
        elif isinstance(item, list):
            pending.extend(((*path, i), v) for i, v in reversed(list(enumerate(item))))
    return None


def _error(loc: Path, what: str) -> FieldError:
    detail = f"{what} holds U+0000 (NUL), a character the store cannot keep"
    return field_error(loc, detail, NUL_RULE)


async def refuse_nul(request: Request) -> None:
    """422 ``nul_character`` at the first query parameter, Idempotency-Key header or string of
    the JSON body that holds NUL."""
    errors = [
        _error(("query", name), f"the name {name!r}" if NUL in name else "the value")
        for name, value in request.query_params.multi_items()
        if NUL in name or NUL in value
    ]
    key = request.headers.get("idempotency-key")
    if key is not None and NUL in key:
        errors.append(_error(("header", "idempotency-key"), "the key"))
    body = await request.body()
    if ESCAPED_NUL in body or b"\x00" in body:
        try:
            found = nul_in(await request.json())
        except ValueError:
            found = None  # not JSON: the route refuses it as such
        if found is not None:
            path, key_holds = found
            what = f"the key {path[-1]!r}" if key_holds else "the string"
            errors.append(_error(("body", *path), what))
    if errors:
        first = errors[0]
        raise InvalidInput(f"{first.pointer or first.parameter}: {first.detail}", errors)
