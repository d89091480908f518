"""What numba compiled is kept under a folder named by a digest of everything it was compiled
from: a change to a function that a compiled function calls from another file compiles the
caller anew (numba's own check looked at the caller's file alone and ran the old code), and
unchanged sources load what was compiled."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

import nanonav

pytestmark = pytest.mark.timeout(120)
CALLEE = """
from nanonav.engine.compiled import inlined


@inlined
def answer() -> int:
    return {value}
"""
CALLER = """
from numba import njit

from nanonav.engine.probe_callee import answer


@njit(cache=True)
def ask() -> int:
    return answer() * 10
"""
ASK = "from nanonav.engine.probe_caller import ask; print(ask())"


def asked(tree: Path) -> int:
    """What the caller answers in a fresh process importing NanoNav from ``tree``."""
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_CACHE_DIR"}
    env["PYTHONPATH"] = str(tree)
    done = subprocess.run([sys.executable, "-c", ASK], capture_output=True, text=True,
                          env=env, cwd=tree, timeout=100, check=True)  # fmt: skip
    return int(done.stdout.strip())


def caches(tree: Path) -> list[Path]:
    return sorted((tree / "nanonav" / "engine" / "__pycache__").glob("compiled-*"))


def test_a_changed_callee_in_another_file_is_compiled_anew(tmp_path: Path) -> None:
    source = Path(nanonav.__file__).resolve().parent
    shutil.copytree(source, tmp_path / "nanonav", ignore=shutil.ignore_patterns("__pycache__"))
    engine = tmp_path / "nanonav" / "engine"
    (engine / "probe_caller.py").write_text(CALLER)
    (engine / "probe_callee.py").write_text(CALLEE.format(value=1))
    assert asked(tmp_path) == 10
    [first] = caches(tmp_path)
    kept = list(first.rglob("probe_caller.ask-*.nbi"))
    assert kept, "the caller was compiled into the digest's folder"
    assert asked(tmp_path) == 10 and caches(tmp_path) == [first]  # unchanged: loaded
    (engine / "probe_callee.py").write_text(CALLEE.format(value=2))
    # the caller's file is as it was: numba's own check (its file's stamp) would load its old
    # machine code and answer 10, as it did before compiled code was kept by digest
    assert asked(tmp_path) == 20
    [second] = caches(tmp_path)
    assert second != first and not first.exists()
