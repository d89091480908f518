"""Cursors for pages listed newest first: opaque to clients, an id underneath.

A cursor is the id to list from, in lowercase hexadecimal. ``CURSOR_PATTERN`` says exactly which
strings are cursors: the OpenAPI document states it, and any string it allows gets a page (a
cursor that names no row lists the rows older than it)."""

from __future__ import annotations

from typing import Annotated

from fastapi import Query

# 1 to 14 hex digits up to MAX_EXACT_INT (0x1fffffffffffff): any 13 digits, or 14 led by a 1.
CURSOR_PATTERN = r"^(?:[0-9a-f]{1,13}|1[0-9a-f]{13})$"

Cursor = Annotated[
    str | None,
    Query(
        pattern=CURSOR_PATTERN,
        description="From `next_cursor` of the page before; absent for the first page.",
    ),
]


def encode_cursor(before_id: int) -> str:
    return format(before_id, "x")


def decode_cursor(cursor: str) -> int:
    """The id a cursor lists from; the pattern has already been checked by the route."""
    return int(cursor, 16)
