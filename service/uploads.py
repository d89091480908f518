"""The line of policies sent to one API process: each network is checked in a process of its
own (``nanonav.rl.onnx_policy``), ``network_checks_at_once`` at a time; up to
``network_checks_waiting`` more wait for a turn without holding a thread; past them a request is
answered 503 ``checks-busy`` with Retry-After at once, before its body is read. So a hundred
uploads at once cost the API a bounded memory, and every other route answers as it would."""

from __future__ import annotations

from collections.abc import AsyncIterator
from contextlib import asynccontextmanager

import anyio
from starlette.types import ASGIApp, Receive, Scope, Send

from service.problems import PROBLEM_BASE, ChecksBusy, Problem, problem_response

UPLOAD_PATH = "/policies"
# Seconds a network waits for a check while others run, before 503
CHECK_WAIT_S = 30.0
# What one upload in the line may hold of the API's memory, in request bodies of the largest
# size: the bytes read, their JSON text, the model decoded, the message to its check's process,
# and the allocator's slack (a hundred uploads of 1.84 MB bodies at once grew the API by 67 MB
# over its 10 places, about 3.6 bodies a place)
BODIES_A_PLACE = 8


def memory_bound_bytes(at_once: int, waiting: int, max_body_bytes: int) -> int:
    """The most that uploads hold of an API process's memory at once, whatever is sent."""
    return (at_once + waiting) * BODIES_A_PLACE * max_body_bytes


class NetworkChecks:
    """The checks of one API process: a turn for each of ``at_once``, a place in line for
    ``waiting`` more."""

    def __init__(self, at_once: int, waiting: int) -> None:
        self.at_once = at_once
        self.places = at_once + waiting
        self.taken = 0
        self._turns: anyio.Semaphore | None = None

    def admit(self) -> bool:
        """Take a place for a request (False: there is none)."""
        if self.taken >= self.places:
            return False
        self.taken += 1
        return True

    def leave(self) -> None:
        self.taken -= 1

    @asynccontextmanager
    async def turn(self) -> AsyncIterator[None]:
        """Wait for a check's turn, ``ChecksBusy`` after ``CHECK_WAIT_S``."""
        if self._turns is None:
            self._turns = anyio.Semaphore(self.at_once)
        turns = self._turns
        got = False
        with anyio.move_on_after(CHECK_WAIT_S):
            await turns.acquire()
            got = True
        if not got:
            raise ChecksBusy(
                f"{self.at_once} networks are being checked already and others wait: send it "
                "again in a moment"
            )
        try:
            yield
        finally:
            turns.release()


class UploadLine:
    """Pure ASGI middleware: a POST to ``UPLOAD_PATH`` takes a place in ``checks``' line before
    its body is read, or is answered 503 at once."""

    def __init__(self, app: ASGIApp, checks: NetworkChecks) -> None:
        self.app = app
        self.checks = checks

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        sending = (
            scope["type"] == "http"
            and scope["method"] == "POST"
            and scope["path"].rstrip("/") == UPLOAD_PATH
        )
        if not sending:
            await self.app(scope, receive, send)
            return
        if not self.checks.admit():
            problem = Problem(
                type=PROBLEM_BASE + ChecksBusy.slug,
                title=ChecksBusy.title,
                status=ChecksBusy.status,
                detail=f"{self.checks.places} policies are being checked or wait for a check "
                "in this process already: send it again in a moment",
                instance=scope.get("path"),
            )
            headers = {**ChecksBusy.headers, "Connection": "close"}  # its body is not read
            await problem_response(problem, headers)(scope, receive, send)
            return
        try:
            await self.app(scope, receive, send)
        finally:
            self.checks.leave()
