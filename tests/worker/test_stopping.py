"""A worker asked to stop does not wait on a housekeeping thread that is stuck (a locked SQLite
file, a slow webhook receiver): it names the thread and goes."""

from __future__ import annotations

import logging
import threading
import time

import pytest

from worker.loop import join_within


def test_a_stuck_thread_holds_a_stopping_worker_only_for_the_bound(
    caplog: pytest.LogCaptureFixture,
) -> None:
    release = threading.Event()
    stuck = threading.Thread(target=release.wait, name="webhooks", daemon=True)
    quick = threading.Thread(target=lambda: None, name="presence", daemon=True)
    stuck.start()
    quick.start()
    started = time.monotonic()
    with caplog.at_level(logging.WARNING, logger="worker.loop"):
        join_within([quick, stuck], 0.3)
    waited = time.monotonic() - started
    release.set()
    assert 0.29 <= waited < 5.0
    assert "webhooks" in caplog.text and "presence" not in caplog.text


def test_threads_that_stop_are_waited_for_without_a_warning(
    caplog: pytest.LogCaptureFixture,
) -> None:
    done = threading.Event()

    def finish() -> None:  # waits a tenth of a second, then says it is done
        if not done.wait(0.1):
            done.set()

    slow = threading.Thread(target=finish, daemon=True)
    slow.start()
    with caplog.at_level(logging.WARNING, logger="worker.loop"):
        join_within([slow], 5.0)
    assert done.is_set() and not slow.is_alive()
    assert caplog.text == ""
