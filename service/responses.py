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
from typing import Any

from fastapi.responses import JSONResponse

from nanonav.finite import finite

logger = logging.getLogger(__name__)


class FiniteJSONResponse(JSONResponse):
    """``JSONResponse`` that writes a NaN or an infinity as null, as pydantic does."""

    def render(self, content: Any) -> bytes:
        try:
            return super().render(content)
        except ValueError:
            found: list[str] = []
            written = finite(content, found)
            if not found:
                raise
            logger.error(
                "an answer held %d numbers JSON cannot carry, written as null: the first at %s",
                len(found),
                found[0],
            )
            return super().render(written)
