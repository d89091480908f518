"""Real processes for the tests: ``python -m worker`` and the API under uvicorn, each logging to
a file, stopped with SIGTERM (and killed if that does not stop them)."""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import httpx

# The first job of a fresh worker may wait for numba to compile (or load) the engine's kernels.
FIRST_JOB_S = 120.0


def free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        port: int = sock.getsockname()[1]
        return port


def clean_environment(**extra: str) -> dict[str, str]:
    """This process's environment without the settings a developer may have exported."""
    env = {
        k: v
        for k, v in os.environ.items()
        if not k.startswith("NANONAV_") and k not in {"DATABASE_URL", "HOST", "PORT"}
    }
    return {**env, **extra}


class _Process:
    """A child process whose output goes to ``log``."""

    def __init__(
        self, command: list[str], log: Path, env: dict[str, str], cwd: Path | None = None
    ) -> None:
        self.log = log
        self._log_file = log.open("wb")
        self.process = subprocess.Popen(
            command, env=env, stdout=self._log_file, stderr=subprocess.STDOUT, cwd=cwd
        )

    def terminate(self, timeout: float = 20.0) -> int:
        if self.process.poll() is None:
            self.process.send_signal(signal.SIGTERM)
        try:
            code = self.process.wait(timeout=timeout)
        except subprocess.TimeoutExpired as error:
            self.process.kill()
            self.process.wait()
            self._log_file.close()
            tail = self.text()[-4000:]
            message = f"no exit within {timeout:g} s of SIGTERM; its log:\n{tail}"
            raise AssertionError(message) from error
        finally:
            self._log_file.close()
        return code

    def text(self) -> str:
        return self.log.read_text()


class Worker(_Process):
    """A ``python -m worker`` process."""

    def __init__(self, database_url: str, log: Path, *args: str, **env: str) -> None:
        environment = {**os.environ, "NANONAV_DATABASE_URL": database_url, **env}
        environment.setdefault("NANONAV_POLL_INTERVAL_S", "0.05")
        super().__init__([sys.executable, "-m", "worker", *args], log, environment)

    def wait_ready(self, timeout: float = FIRST_JOB_S) -> None:
        """Until the worker has loaded the engine and looks at the queue."""
        deadline = time.monotonic() + timeout
        while " ready on " not in self.text():
            assert self.process.poll() is None, self.text()
            assert time.monotonic() < deadline, "the worker did not get ready"
            time.sleep(0.05)


class ApiServer(_Process):
    """The API as ``make run`` serves it: ``nanonav api``, with its limits and shutdown grace."""

    def __init__(
        self, database_url: str, log: Path, *, cwd: Path | None = None, **env: str
    ) -> None:
        self.url = f"http://127.0.0.1:{free_port()}"
        command = [sys.executable, "-m", "nanonav.cli", "api", "--host", "127.0.0.1",
                   "--port", self.url.rsplit(":", 1)[1]]  # fmt: skip
        environment = clean_environment(NANONAV_DATABASE_URL=database_url, **env)
        super().__init__(command, log, environment, cwd)

    def wait_ready(self, timeout: float = 60.0) -> None:
        """Until ``/healthz`` answers 200."""
        deadline = time.monotonic() + timeout
        while True:
            assert self.process.poll() is None, self.text()
            assert time.monotonic() < deadline, "the API did not start:\n" + self.text()
            try:
                if httpx.get(f"{self.url}/healthz", timeout=2).status_code == 200:
                    return
            except httpx.TransportError:
                pass
            time.sleep(0.05)


def sandbox_of(parent: int, timeout: float = 60.0) -> int:
    """The process id of the network's sandboxed process (``nanonav.rl.sandbox``) that the
    process ``parent`` runs now, waiting for one."""
    return child_of(parent, b"nanonav.rl.sandbox", timeout)


def child_of(parent: int, command: bytes, timeout: float = 60.0) -> int:
    """The process id of a child of ``parent`` whose command line holds ``command``, waiting
    for one."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        for entry in Path("/proc").iterdir():
            if not entry.name.isdigit():
                continue
            try:
                stat = (entry / "stat").read_text()
                line = (entry / "cmdline").read_bytes()
            except OSError:
                continue
            if int(stat.rsplit(")", 1)[1].split()[1]) == parent and command in line:
                return int(entry.name)
        time.sleep(0.05)
    raise AssertionError(f"process {parent} runs no {command.decode()!r}")


def gone(pid: int, timeout: float = 10.0) -> bool:
    """Whether process ``pid`` is gone (or a zombie) within ``timeout``."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        try:
            state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
        except OSError:
            return True
        if state == "Z":
            return True
        time.sleep(0.05)
    return False
