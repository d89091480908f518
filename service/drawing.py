"""Pictures drawn on demand, off the event loop, one at a time, each drawn once.

Matplotlib is not thread-safe, so one API process draws one picture at a time, in a worker
thread, while the event loop goes on answering other requests. Two requests for the same
picture share one drawing. Requests that would wait behind too many drawings are refused
with 503 and ``Retry-After`` instead of queueing without bound.
"""

from __future__ import annotations

import asyncio
from collections.abc import Callable, Hashable

import anyio
import anyio.to_thread

from service.problems import ProblemError


class DrawingBusy(ProblemError):
    status = 503
    slug = "drawing-busy"
    title = "Too many pictures being drawn"
    headers = {"Retry-After": "2"}  # noqa: RUF012


class Drawer:
    """Runs drawing functions in a thread, one at a time, at most ``max_waiting`` pending."""

    def __init__(self, max_waiting: int) -> None:
        self.max_waiting = max_waiting
        self._limiter = anyio.CapacityLimiter(1)
        self._pending: dict[Hashable, asyncio.Future[bytes]] = {}

    async def draw(self, key: Hashable, draw: Callable[[], bytes]) -> bytes:
        """``draw()``'s PNG; a drawing already under way for ``key`` is awaited, not repeated."""
        pending = self._pending.get(key)
        if pending is None:
            if len(self._pending) >= self.max_waiting:
                raise DrawingBusy(
                    f"{len(self._pending)} pictures are being drawn; try again in a moment"
                )
            pending = asyncio.ensure_future(anyio.to_thread.run_sync(draw, limiter=self._limiter))
            self._pending[key] = pending
            pending.add_done_callback(lambda done: self._forget(key, done))
        # A client that goes away does not cancel a drawing others may be waiting for.
        return await asyncio.shield(pending)

    def _forget(self, key: Hashable, done: asyncio.Future[bytes]) -> None:
        self._pending.pop(key, None)
        if not done.cancelled():
            done.exception()  # retrieved here too, in case every waiter went away


def kept_name(name: str, version: int) -> str:
    """The name the picture ``name`` is kept under: its own at the first version of its drawing,
    else with the version (``learning.v2``), so that a copy of an older drawing, still in the
    store until its job or study goes, is never served again."""
    return name if version == 1 else f"{name}.v{version}"
