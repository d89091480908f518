"""An API process that ``nanonav api --processes N`` started stops when its supervisor dies.

uvicorn starts the N processes as ``multiprocessing`` children of one supervisor. Killed with
SIGKILL, the supervisor cannot stop them, and they would go on serving, unsupervised, on the
port; nobody would replace or stop them. A process started on its own (one process, or a test)
has no such parent and is left alone.
"""

from __future__ import annotations

import asyncio
import logging
import multiprocessing
import os
import signal

logger = logging.getLogger(__name__)

ORPHAN_CHECK_S = 1.0


async def stop_when_orphaned() -> None:
    """Until cancelled: once the supervisor is gone, ask this process to stop as SIGTERM does
    (uvicorn then ends open requests within its grace, and the app's lifespan)."""
    if multiprocessing.parent_process() is None:
        return
    parent = os.getppid()
    while os.getppid() == parent:
        await asyncio.sleep(ORPHAN_CHECK_S)
    logger.warning("the API's supervisor (%d) is gone; stopping", parent)
    os.kill(os.getpid(), signal.SIGTERM)
