"""The ``nanonav`` command as one end of a shell pipe whose other end leaves early."""

import json
import os
import subprocess
import sys
from pathlib import Path

from nanonav.cli.common import EXIT_PIPE_CLOSED

SMALL = {"learning": {"episodes": 2, "max_steps": 100}, "obstacles": {"count": 0}}


def test_a_reader_that_leaves_early_ends_the_command_quietly(tmp_path: Path) -> None:
    path = tmp_path / "scenario.json"
    path.write_text(json.dumps(SMALL), encoding="utf-8")
    read, write = os.pipe()
    os.close(read)  # as `| head` once it has its lines: nobody reads what follows
    try:
        done = subprocess.run(
            [sys.executable, "-m", "nanonav.cli", "run", "--scenario", str(path), "--json"],
            stdout=write, stderr=subprocess.PIPE, text=True, timeout=300, check=False,
        )  # fmt: skip
    finally:
        os.close(write)
    assert "Traceback" not in done.stderr and "BrokenPipeError" not in done.stderr, done.stderr
    assert done.returncode == EXIT_PIPE_CLOSED
