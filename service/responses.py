"""The JSON a route writes itself: never a number JSON cannot carry.

Answers of a route's response model are written by pydantic, which writes NaN and infinities as
null; the routes that build their answer as plain data (large arrays: a trajectory, a Q-table)
answer with ``FiniteJSONResponse``, which writes them as null too, where Starlette's
``JSONResponse`` would fail the request with a 500. Results are kept finite where they are made
(the worker stores a metric that is not as null, a policy's values are bounded, means over robots
cannot overflow): this is the backstop, and it logs what it replaced.
"""

from __future__ import annotations

import logging
import math
from typing import Any

from fastapi.responses import JSONResponse

logger = logging.getLogger(__name__)


class FiniteJSONResponse(JSONResponse):
    """``JSONResponse`` that writes a NaN or an infinity as null, as pydantic does."""

    def render(self, content: Any) -> bytes:
        try:
            return super().render(content)
        except ValueError:
            found: list[str] = []
            finite = _finite(content, "#", found)
            if not found:
                raise
            logger.error(
                "an answer held %d numbers JSON cannot carry, written as null: the first at %s",
                len(found),
                found[0],
            )
            return super().render(finite)


def _finite(value: Any, pointer: str, found: list[str]) -> Any:
    """``value`` with every non-finite float as None; ``found`` gets the JSON pointer of each."""
    if isinstance(value, float):
        if math.isfinite(value):
            return value
        found.append(pointer)
        return None
    if isinstance(value, dict):
        return {k: _finite(v, f"{pointer}/{_token(k)}", found) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_finite(v, f"{pointer}/{i}", found) for i, v in enumerate(value)]
    return value


def _token(key: Any) -> str:
    return str(key).replace("~", "~0").replace("/", "~1")
