"""Numbers read from text nothing has validated yet: a cookie, a query string, a header.

``str.isdigit`` takes ``²`` and ``①``, which ``int`` then refuses with an error, and the
Arabic-Indic one (U+0661), which ``int`` reads as 1; ``int`` also takes ``01``, `` 1`` and
``+1``, so one number would have many spellings. Here a number is spelled one way only: ASCII
digits, the first not 0, no longer than the largest value allowed.
"""

from __future__ import annotations

from nanonav.scenario import MAX_EXACT_INT


def positive_int(text: str, *, maximum: int = MAX_EXACT_INT) -> int | None:
    """The integer ``text`` spells, if it is one from 1 to ``maximum`` written canonically
    (ASCII digits without a leading zero); else None."""
    if not 0 < len(text) <= len(str(maximum)) or text[0] == "0":
        return None
    if not (text.isascii() and text.isdigit()):
        return None
    value = int(text)
    return value if value <= maximum else None
