"""Cursors for pages listed newest first: opaque to clients, an id underneath."""

from __future__ import annotations

import base64
import binascii

from service.problems import InvalidInput, field_error


def encode_cursor(before_id: int) -> str:
    return base64.urlsafe_b64encode(str(before_id).encode()).decode().rstrip("=")


def decode_cursor(cursor: str) -> int:
    try:
        text = base64.urlsafe_b64decode(cursor + "=" * (-len(cursor) % 4)).decode("ascii")
        if not text.isdigit() or not 0 < int(text) < 2**63:
            raise ValueError(text)
        return int(text)
    except (binascii.Error, ValueError, UnicodeDecodeError):
        raise InvalidInput(
            "cursor: not a cursor this API gave out",
            [field_error(["query", "cursor"], "not a cursor this API gave out", "cursor_invalid")],
        ) from None
