"""Child processes that go when their parent goes: a network's sandbox, a worker's compile.
A child left behind by a killed parent would go on spending memory and processor for nobody."""

from __future__ import annotations

import os
import signal
import sys


def die_with_parent(parent: int) -> None:
    """From now, this process is killed when the thread that started it ends (Linux's
    ``PR_SET_PDEATHSIG``); if ``parent`` is already gone, it exits now. Elsewhere a no-op."""
    if sys.platform != "linux":
        return
    import ctypes

    libc = ctypes.CDLL(None, use_errno=True)
    pr_set_pdeathsig = 1
    libc.prctl(pr_set_pdeathsig, signal.SIGKILL, 0, 0, 0)
    if os.getppid() != parent:  # it died before the request was made
        os._exit(1)
