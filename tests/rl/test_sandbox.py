"""A network runs in a process of its own, with limits: a crash, a hang, a run past its CPU
seconds or its memory ends that process and is reported, and the process that asked goes on.
The faults are real: the audit's model raising SIGFPE in ONNX Runtime, and signals sent to the
network's process as a crash or a hang would stop it."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from nanonav.rl.graph import InvalidModel
from nanonav.rl.onnx_policy import Limits, NetworkPolicy, check_model
from nanonav.rl.sandbox import SandboxFailed
from nanonav.rl.stops import Stopped
from tests.processes import sandbox_of
from tests.rl import models

pytestmark = pytest.mark.timeout(120)
LIMIT = 2_000_000
RAW_RUN = """
import sys, numpy as np, onnxruntime
session = onnxruntime.InferenceSession(sys.stdin.buffer.read(), providers=["CPUExecutionProvider"])
session.run(None, {"observation": np.full((2, 7), float(sys.argv[1]), np.float32)})
"""


def raw_run(model: bytes, value: float) -> int:
    """The exit status of a process that runs ``model`` in ONNX Runtime as it is, unchecked,
    on two observations of ``value``."""
    done = subprocess.run([sys.executable, "-c", RAW_RUN, str(value)], input=model,
                          capture_output=True, timeout=60, check=False)  # fmt: skip
    return done.returncode


def test_the_audits_model_kills_onnx_runtime_and_is_refused_before_it_runs() -> None:
    crashing = models.integer_division(7)
    assert len(crashing) < 500
    assert raw_run(crashing, 0.0) == -signal.SIGFPE
    later = models.integer_division(7, only_when_positive=True)
    assert raw_run(later, 0.0) == 0 and raw_run(later, 1.0) == -signal.SIGFPE
    for model in (crashing, later):
        with pytest.raises(InvalidModel, match=r"\(Mod\): Mod is not an operator"):
            check_model(model, 7, 4, max_bytes=LIMIT)


def test_a_crash_of_the_networks_process_is_reported_and_the_next_network_runs() -> None:
    rows = np.ones((5, 7))
    with NetworkPolicy(models.mlp(7, 4), 7, 4, max_bytes=LIMIT) as policy:
        assert policy(rows).shape == (5,)
        os.kill(policy._box.pid, signal.SIGFPE)
        with pytest.raises(SandboxFailed, match=r"killed by SIGFPE for one call of 5 observations"):
            policy(rows)
    with NetworkPolicy(models.mlp(7, 4), 7, 4, max_bytes=LIMIT) as policy:
        assert policy(rows).shape == (5,)


def test_a_call_that_hangs_is_stopped_at_its_limit() -> None:
    limits = Limits(call_s=0.5)
    with NetworkPolicy(models.mlp(7, 4), 7, 4, max_bytes=LIMIT, limits=limits) as policy:
        os.kill(policy._box.pid, signal.SIGSTOP)
        started = time.monotonic()
        with pytest.raises(SandboxFailed, match=r"took longer than 0.5 s for one call of 3 obs"):
            policy(np.ones((3, 7)))
        assert 0.5 <= time.monotonic() - started < 3.0


def test_a_call_stops_within_itself_when_the_run_is_told_to_stop() -> None:
    """A job cancelled or past its time limit while its network decides: ``keep_going`` is
    asked while the call runs, and the call ends within about a tenth of a second."""
    asked_at: list[float] = []
    stop_at = [float("inf")]

    def keep_going() -> bool:
        asked_at.append(time.monotonic())
        return time.monotonic() < stop_at[0]

    with NetworkPolicy(models.mlp(7, 4), 7, 4, max_bytes=LIMIT, keep_going=keep_going) as policy:
        os.kill(policy._box.pid, signal.SIGSTOP)  # a call that would never end
        started = time.monotonic()
        stop_at[0] = started + 0.3
        asked_at.clear()
        with pytest.raises(Stopped):
            policy(np.ones((3, 7)))
        assert time.monotonic() - started < 1.5 and len(asked_at) >= 2


def test_a_network_past_its_cpu_seconds_is_killed_saying_so() -> None:
    heavy = models.dense_stack(7, 4, units=1000, layers=3)
    limits = Limits(run_cpu_s=3.0)
    with NetworkPolicy(heavy, 7, 4, max_bytes=LIMIT, limits=limits) as policy:
        rows = np.ones((policy.info.cost.rows_per_call, 7))
        deadline = time.monotonic() + 60
        with pytest.raises(SandboxFailed, match=r"killed by SIGXCPU .*more than its 3 s of CPU"):
            while time.monotonic() < deadline:
                policy(rows)


def test_a_network_past_its_memory_fails_its_call_saying_so() -> None:
    """Five values of (batch, 10,000) live at once, 240 kB an observation (under the cap): a
    call of 1,118 observations needs about 270 MB more than the process's 0.2 GB."""
    wide = models.kept_alive(7, 4, values=5, summed_by="Add")
    limits = Limits(memory_bytes=350 * 1024 * 1024)
    with NetworkPolicy(wide, 7, 4, max_bytes=LIMIT, limits=limits) as policy:
        assert policy(np.ones((10, 7))).shape == (10,)
        with pytest.raises(SandboxFailed, match=r"bytes of memory"):
            policy(np.ones((policy.info.cost.rows_per_call, 7)))


def test_a_check_that_fails_in_its_process_is_a_refused_model() -> None:
    """At upload a crash of the check's process is the model's refusal (a 422): the process is
    killed by SIGSEGV as soon as it starts."""

    def crash() -> None:
        os.kill(sandbox_of(os.getpid()), signal.SIGSEGV)

    killer = threading.Thread(target=crash)
    killer.start()
    with pytest.raises(InvalidModel, match=r"killed by SIGSEGV while its model was checked"):
        check_model(models.mlp(7, 4), 7, 4, max_bytes=LIMIT)
    killer.join()


def test_the_networks_process_starts_empty_handed(monkeypatch: pytest.MonkeyPatch) -> None:
    """No variable of its parent's but PATH and the locale's, so no key or secret; an empty
    working folder of its own, so no relative path reaches a file; removed when it ends."""
    monkeypatch.setenv("NANONAV_API_KEYS", "secret-key-0123456789abcdef0123456789")
    monkeypatch.setenv("NANONAV_SESSION_SECRET", "another-secret")
    with NetworkPolicy(models.mlp(7, 4), 7, 4, max_bytes=LIMIT) as policy:
        pid = sandbox_of(os.getpid())
        entries = Path(f"/proc/{pid}/environ").read_text().split("\0")
        environment = dict(entry.split("=", 1) for entry in entries if entry)
        folder = os.readlink(f"/proc/{pid}/cwd")
        assert os.listdir(folder) == []
        assert policy(np.zeros((2, 7))).shape == (2,)
    assert not any(value in ("secret-key-0123456789abcdef0123456789", "another-secret")
                   for value in environment.values())  # fmt: skip
    assert set(environment) <= {"PATH", "LANG", "LC_ALL", "OPENBLAS_CORETYPE",
                                "OPENBLAS_L2_SIZE", "HOME", "TMPDIR", "OMP_NUM_THREADS",
                                "PYTHONDONTWRITEBYTECODE", "PYTHONPATH"}  # fmt: skip
    assert environment["HOME"] == environment["TMPDIR"] != folder
    assert os.path.dirname(environment["HOME"]) == os.path.dirname(folder)
    assert not os.path.exists(folder) and not os.path.exists(environment["HOME"])


def test_a_model_naming_a_file_beside_its_caller_learns_nothing_of_it(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The file beside the caller is refused, and its bytes are not in the refusal."""
    here = tmp_path
    (here / "secret.txt").write_bytes(b"TOPSECRETBYTES!!")
    monkeypatch.chdir(here)
    data = models.file_reader(7, 4, "secret.txt", form="sparse")
    with pytest.raises(InvalidModel) as refused:
        check_model(data, 7, 4, max_bytes=LIMIT)
    assert "TOPSECRE" not in str(refused.value)
    assert str(int.from_bytes(b"TOPSECRE", "little")) not in str(refused.value)
