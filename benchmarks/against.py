"""Old and new side by side in one run: a benchmark's measurement made in this tree and in another
git revision of it, alternately, case by case, so that both meet the same machine and the same
load. The revision is checked out once into a worktree under the system's temporary directory;
each measurement runs in a fresh process (``python SCRIPT --measure CASE``) whose ``nanonav``
is that tree's, printing its figure as JSON on its last line.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent


def worktree(revision: str) -> Path:
    """A checkout of ``revision`` (made once, kept for later runs)."""
    commit = subprocess.run(
        ["git", "-C", str(REPO), "rev-parse", "--verify", f"{revision}^{{commit}}"],
        check=True, capture_output=True, text=True,
    ).stdout.strip()  # fmt: skip
    path = Path(tempfile.gettempdir()) / f"nanonav-{commit[:12]}"
    if not (path / "nanonav").is_dir():
        subprocess.run(
            ["git", "-C", str(REPO), "worktree", "add", "--force", "--detach", str(path), commit],
            check=True, capture_output=True,
        )  # fmt: skip
    return path


def measure(tree: Path, script: Path, case: str) -> float:
    """The figure ``script --measure case`` prints, with ``nanonav`` imported from ``tree``."""
    env = {**os.environ, "PYTHONPATH": str(tree)}
    done = subprocess.run(
        [sys.executable, str(script), "--measure", case],
        check=True, capture_output=True, text=True, env=env, cwd=tempfile.gettempdir(),
    )  # fmt: skip
    return float(json.loads(done.stdout.strip().splitlines()[-1]))


def side_by_side(script: Path, cases: list[str], revision: str) -> dict[str, tuple[float, float]]:
    """Each case measured at ``revision`` and in this tree, one after the other, printed as a
    table as it goes; returns {case: (old, new)}."""
    old_tree = worktree(revision)
    print(f"{'case':<40}{revision[:12]:>14}{'this tree':>14}{'new/old':>9}")
    print("-" * 77)
    out = {}
    for case in cases:
        old = measure(old_tree, script, case)
        new = measure(REPO, script, case)
        out[case] = (old, new)
        print(f"{case:<40}{old:>14,.0f}{new:>14,.0f}{new / old:>9.2f}", flush=True)
    return out
