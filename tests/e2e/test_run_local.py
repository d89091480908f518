"""What ``make run`` runs, and ``python -m worker --concurrency``, as real processes."""

from __future__ import annotations

import os
import re
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import httpx
import pytest

from nanonav.run_local import port_in_use
from nanonav.store import JobStatus, JobStore
from nanonav.store.migrate import upgrade
from tests.processes import child_of, clean_environment, free_port

pytestmark = pytest.mark.timeout(240)
TINY: dict[str, Any] = {"robots": {"count": 2}, "learning": {"episodes": 1, "max_steps": 40}}


@contextmanager
def running(
    command: list[str], log: Path, env: dict[str, str], cwd: Path | None = None
) -> Iterator[subprocess.Popen[bytes]]:
    """``command`` as a real process writing to ``log``; killed if the block leaves it alive."""
    with log.open("wb") as out:
        process = subprocess.Popen(command, cwd=cwd, env=env, stdout=out, stderr=subprocess.STDOUT)
        try:
            yield process
        finally:
            if process.poll() is None:
                process.kill()
                process.wait()


def until_logged(process: subprocess.Popen[bytes], log: Path, text: str, deadline: float) -> None:
    """Wait until ``process`` writes ``text`` to ``log``, while it lives and before ``deadline``."""
    while text not in log.read_text():
        assert process.poll() is None, log.read_text()
        assert time.monotonic() < deadline, log.read_text()
        time.sleep(0.1)


def test_run_local_migrates_serves_runs_a_job_and_stops_on_ctrl_c(tmp_path: Path) -> None:
    port = free_port()
    log = tmp_path / "run.log"
    command = [sys.executable, "-m", "nanonav.run_local"]
    with running(command, log, clean_environment(PORT=str(port)), cwd=tmp_path) as process:
        deadline = time.monotonic() + 120
        until_logged(process, log, "the API is at", deadline)
        assert f"http://127.0.0.1:{port}" in log.read_text()
        assert (tmp_path / "var" / "nanonav.db").exists()
        shown = re.search(r"the command line is (\S+)", log.read_text())
        assert shown is not None and Path(shown.group(1)).is_file()
        until_logged(process, log, "a worker is ready", deadline)
        # waiting for the worker logs nothing: only the one poll that found the API up
        assert log.read_text().count('"GET /healthz HTTP/1.1" 200') == 1, log.read_text()
        with httpx.Client(base_url=f"http://127.0.0.1:{port}", timeout=10) as client:
            health = client.get("/healthz").json()
            assert health["workers"]["seen"] == 1 and health["note"] is None
            assert health["status"] == "ok"
            assert health["queue"] == {"queued": 0, "running": 0, "oldest_queued_at": None}
            job_id = client.post("/jobs", json=TINY).json()["id"]
            while client.get(f"/jobs/{job_id}").json()["status"] != "succeeded":
                assert time.monotonic() < deadline, log.read_text()
                time.sleep(0.1)
        process.send_signal(signal.SIGINT)
        assert process.wait(timeout=30) == 0
    text = log.read_text()
    assert "nanonav: stopped" in text
    assert "Traceback" not in text
    assert f'"GET /jobs/{job_id} HTTP/1.1" 200' in text, "real requests are still logged"


def test_worker_concurrency_runs_jobs_in_several_processes(tmp_path: Path) -> None:
    url = f"sqlite:///{tmp_path / 'nanonav.db'}"
    upgrade(url)
    store = JobStore.from_url(url)
    ids = [store.enqueue({**TINY, "seed": s}, robot_steps=1, episodes=2).id for s in range(6)]
    log = tmp_path / "worker.log"
    command = [sys.executable, "-m", "worker", "--concurrency", "2"]
    env = clean_environment(NANONAV_DATABASE_URL=url, NANONAV_POLL_INTERVAL_S="0.05")
    with running(command, log, env) as process:
        deadline = time.monotonic() + 180

        def ready() -> set[str]:
            return set(re.findall(r"worker (\d+) ready", log.read_text()))

        # One child may finish all six jobs before the other is ready: wait for both.
        while len(ready()) < 2 or any(store.get(i).status is not JobStatus.SUCCEEDED for i in ids):
            assert process.poll() is None, log.read_text()
            assert time.monotonic() < deadline, log.read_text()
            time.sleep(0.2)
        process.send_signal(signal.SIGTERM)
        assert process.wait(timeout=30) == 0
    store.close()
    assert len(ready()) == 2


def test_the_nanonav_migrate_api_and_worker_commands(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from nanonav.cli import main
    from nanonav.store.db import make_engine
    from nanonav.store.migrate import at_head

    url = f"sqlite:///{tmp_path / 'cli.db'}"
    monkeypatch.setenv("DATABASE_URL", url)
    monkeypatch.delenv("NANONAV_DATABASE_URL", raising=False)
    assert main(["migrate"]) == 0
    engine = make_engine(url)
    assert at_head(engine)
    engine.dispose()
    assert main(["api", "--port", "70000"]) == 2
    assert main(["api", "--processes", "0"]) == 2
    assert main(["worker", "--concurrency", "0"]) == 2

    port = free_port()
    nanonav = str(Path(sys.executable).with_name("nanonav"))
    env = clean_environment(DATABASE_URL=url, NANONAV_POLL_INTERVAL_S="0.05")
    api_log = (tmp_path / "api.log").open("wb")
    api = subprocess.Popen(
        [nanonav, "api", "--port", str(port), "--processes", "2"],
        env=env,
        stdout=api_log,
        stderr=subprocess.STDOUT,
    )
    worker = subprocess.Popen(
        [nanonav, "worker", "--concurrency", "1"],
        env=env,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    try:
        deadline = time.monotonic() + 120
        with httpx.Client(base_url=f"http://127.0.0.1:{port}", timeout=10) as client:
            while True:
                try:
                    job_id = client.post("/jobs", json=TINY).json()["id"]
                    break
                except httpx.TransportError:
                    assert api.poll() is None and time.monotonic() < deadline
                    time.sleep(0.1)
            while client.get(f"/jobs/{job_id}").json()["status"] != "succeeded":
                assert worker.poll() is None and time.monotonic() < deadline
                time.sleep(0.1)
    finally:
        for process in (api, worker):
            process.send_signal(signal.SIGTERM)
        codes = [process.wait(timeout=30) for process in (api, worker)]
        api_log.close()
    # uvicorn shuts down gracefully, then re-raises the signal it caught.
    assert codes in ([0, 0], [-signal.SIGTERM, 0])
    text = (tmp_path / "api.log").read_text()
    assert len(set(re.findall(r"Started server process \[(\d+)\]", text))) == 2, text
    assert text.count("Application shutdown complete") == 2, text


def test_run_local_on_postgresql_migrates_and_serves(postgres_url: str, tmp_path: Path) -> None:
    """The documentation's ``DATABASE_URL=postgresql://... make run``, on the real server."""
    port = free_port()
    log = tmp_path / "run.log"
    command = [sys.executable, "-m", "nanonav.run_local"]
    env = clean_environment(PORT=str(port), DATABASE_URL=postgres_url)
    with running(command, log, env, cwd=tmp_path) as process:
        deadline = time.monotonic() + 120
        until_logged(process, log, "the API is at", deadline)
        with httpx.Client(base_url=f"http://127.0.0.1:{port}", timeout=10) as client:
            health = client.get("/healthz").json()
            assert health["status"] == "ok" and health["database"] is True
            job_id = client.post("/jobs", json=TINY).json()["id"]
        store = JobStore.from_url(postgres_url)
        assert store.get(job_id).scenario["robots"]["count"] == 2
        store.close()
        process.send_signal(signal.SIGINT)
        assert process.wait(timeout=30) == 0
    assert not (tmp_path / "var").exists(), "nothing went to a SQLite file"
    assert "Traceback" not in log.read_text()


def test_a_database_whose_driver_is_missing_is_one_line_naming_the_extra() -> None:
    """Without psycopg (the ``postgres`` extra), a PostgreSQL URL is refused in one line."""
    blocked = (
        "import runpy, sys; sys.modules['psycopg'] = None; "
        "runpy.run_module('nanonav.run_local', run_name='__main__')"
    )
    env = clean_environment(DATABASE_URL="postgresql://user:secret@127.0.0.1:1/nanonav")
    done = subprocess.run(
        [sys.executable, "-c", blocked], env=env, capture_output=True, text=True, timeout=60
    )
    assert done.returncode == 2 and done.stdout == ""
    [line] = done.stderr.splitlines()
    assert "needs the psycopg driver" in line and "pip install -e '.[postgres]'" in line
    assert "secret" not in line


@pytest.mark.parametrize(
    ("url", "extra"),
    [("postgresql://u@h/d", True), ("postgresql+psycopg://u@h/d", True), ("", False)],
)
def test_make_run_installs_the_driver_its_database_url_needs(url: str, extra: bool) -> None:
    root = Path(__file__).resolve().parents[2]
    env = clean_environment(DATABASE_URL=url) if url else clean_environment()
    for inherited in ("MAKEFLAGS", "MFLAGS", "MAKELEVEL"):  # when `make test` runs this test
        env.pop(inherited, None)
    planned = subprocess.run(
        ["make", "--no-print-directory", "-n", "run"],
        cwd=root, env=env, capture_output=True, text=True, check=True,
    ).stdout  # fmt: skip
    assert ("'.[postgres]'" in planned) is extra, planned
    assert planned.rstrip().endswith("-m nanonav.run_local")


def consecutive_ports_taken(count: int) -> list[socket.socket]:
    """``count`` listening sockets on consecutive ports of 127.0.0.1."""
    while True:
        first = socket.socket()
        first.bind(("127.0.0.1", 0))
        first.listen()
        taken, base = [first], first.getsockname()[1]
        try:
            for offset in range(1, count):
                sock = socket.socket()
                taken.append(sock)
                sock.bind(("127.0.0.1", base + offset))
                sock.listen()
        except OSError:
            for sock in taken:
                sock.close()
            continue
        return taken


def test_a_port_in_use_is_one_line_naming_a_free_one_before_anything_starts(
    tmp_path: Path,
) -> None:
    """Another server on the port, and on the next: ``make run`` says so and names a port that
    is free, instead of taking that server's /healthz for its own API's."""
    taken = consecutive_ports_taken(2)
    port = taken[0].getsockname()[1]
    try:
        done = subprocess.run(
            [sys.executable, "-m", "nanonav.run_local"],
            cwd=tmp_path,
            env=clean_environment(PORT=str(port)),
            capture_output=True,
            text=True,
            timeout=60,
        )
    finally:
        for sock in taken:
            sock.close()
    assert done.returncode == 1 and done.stdout == ""
    [line] = done.stderr.splitlines()
    assert f"127.0.0.1:{port} is in use" in line
    suggested = int(line.split("make run PORT=")[1].split("`")[0])
    assert suggested > port + 1, "the next port was taken too"
    assert not port_in_use("127.0.0.1", suggested)
    assert not (tmp_path / "var").exists(), "nothing was migrated or started"


def test_run_local_starts_another_worker_when_its_worker_dies(tmp_path: Path) -> None:
    """A worker killed (as the kernel's out-of-memory killer would) is not a dead service: the
    API goes on, another worker starts, saying how the first died, and jobs run."""
    port = free_port()
    log = tmp_path / "run.log"
    command = [sys.executable, "-m", "nanonav.run_local"]
    with running(command, log, clean_environment(PORT=str(port)), cwd=tmp_path) as process:
        deadline = time.monotonic() + 180
        until_logged(process, log, "a worker is ready", deadline)
        worker = child_of(process.pid, b"-m\0worker\0")
        os.kill(worker, signal.SIGKILL)
        until_logged(process, log, "the worker was killed by SIGKILL (out of memory?); "
                     "starting another", deadline)  # fmt: skip
        with httpx.Client(base_url=f"http://127.0.0.1:{port}", timeout=10) as client:
            job_id = client.post("/jobs", json=TINY).json()["id"]
            while client.get(f"/jobs/{job_id}").json()["status"] != "succeeded":
                assert time.monotonic() < deadline, log.read_text()
                time.sleep(0.1)
        assert child_of(process.pid, b"-m\0worker\0") != worker
        process.send_signal(signal.SIGINT)
        assert process.wait(timeout=30) == 0
