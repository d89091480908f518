"""The engine's first start: wall time and peak memory of a new user's first run, first
environment and first network policy, each in a fresh process from an empty compile cache.

    python benchmarks/first_start.py                 # this tree (about four minutes)
    python benchmarks/first_start.py --against REV   # REV's and this tree's, side by side

The three starts, each a new process with ``NUMBA_CACHE_DIR`` pointed at an empty folder:

- ``nanonav run``: ``nanonav run --preset paper-single`` (pictures written to a scratch folder);
- ``NanoNavEnv``: ``NanoNavEnv({"preset": "tumour-microswimmers"})``, ``reset`` and 20 random
  steps;
- ``network policy``: a 64x64 MLP (ONNX), read from its file, evaluated in a 'paper-single'
  evaluation by the service's path (``rl.evaluate``), as a worker runs a job that names a
  network (the file is written before the clock starts).

Peak memory is the process's largest resident set (``wait4``'s ``ru_maxrss``; a network's
sandboxed process is its child and not counted). ``--against`` runs each start at a git
revision (a worktree, ``against.worktree``) and in this tree, one after the other, on the same
machine. Targets (the issue's): at most 60 s and 1.5 GB each.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from against import REPO, worktree

TARGET_S = 60.0
TARGET_BYTES = 1.5e9
ENV_STEPS = 20
# the observation's layout, where the tree at hand keeps it (engine/worlds.py before
# engine/observations.py), so that an old tree and a new one run the same start
OBSERVATIONS = (
    "try:\n    from nanonav.engine.observations import action_labels, observation_of\n"
    "except ImportError:\n    from nanonav.engine.worlds import action_labels, observation_of\n"
)
STARTS = {
    "nanonav run": "from nanonav.cli import main; raise SystemExit(main(['run', '--preset', "
    "'paper-single', '--out', {out!r}]))",
    # random actions, drawn from a seeded space; an episode that ends is begun again
    "NanoNavEnv": "from nanonav.env import NanoNavEnv\n"
    "env = NanoNavEnv({{'preset': 'tumour-microswimmers'}}); env.reset(seed=0)\n"
    "env.action_space.seed(0)\n"
    f"for _ in range({ENV_STEPS}):\n"
    "    _, _, ended, cut, _ = env.step(env.action_space.sample())\n"
    "    if ended or cut: env.reset()",
    # the model read from a file, as a user's trained network is (``MODEL`` made it, untimed)
    "network policy": OBSERVATIONS + "from pathlib import Path; "
    "from nanonav.rl.evaluate import evaluate; from nanonav.rl.onnx_policy import NetworkPolicy; "
    "from nanonav.scenario import Scenario; "
    "s = Scenario.model_validate({{'preset': 'paper-single', 'learning': {{'episodes': 0}}}}); "
    "w = observation_of(s).columns.size; n = len(action_labels(s)); "
    "m = Path({model!r}).read_bytes(); "
    "p = NetworkPolicy(m, w, n, max_bytes=len(m)); evaluate(s, p); "
    "getattr(p, 'close', lambda: None)()",
}
# The network's ONNX file, written before the clock starts: building it with the ``onnx``
# package (2.3 s of imports) is not part of evaluating one.
MODEL = (
    "import sys; sys.path.insert(0, {benchmarks!r}); from pathlib import Path; "
    "from network_policy import mlp\n" + OBSERVATIONS + "from pathlib import Path; "
    "from nanonav.scenario import Scenario; "
    "s = Scenario.model_validate({{'preset': 'paper-single', 'learning': {{'episodes': 0}}}}); "
    "Path({model!r}).write_bytes(mlp(observation_of(s).columns.size, len(action_labels(s))))"
)


def first_start(tree: Path, name: str) -> tuple[float, int]:
    """Wall seconds and peak resident bytes of start ``name`` run with NanoNav from ``tree``,
    from an empty compile cache."""
    with tempfile.TemporaryDirectory() as cache, tempfile.TemporaryDirectory() as out:
        names = {"out": out, "benchmarks": str(Path(__file__).resolve().parent),
                 "model": str(Path(out) / "policy.onnx")}  # fmt: skip
        code = STARTS[name].format(**names)
        env = {**os.environ, "PYTHONPATH": str(tree), "NUMBA_CACHE_DIR": cache}
        if "{model" in STARTS[name]:  # with a cache of its own, thrown away
            with tempfile.TemporaryDirectory() as other:
                subprocess.run([sys.executable, "-c", MODEL.format(**names)],
                               env={**env, "NUMBA_CACHE_DIR": other}, check=True)  # fmt: skip
        started = time.perf_counter()
        process = subprocess.Popen([sys.executable, "-c", code], env=env, cwd=out,
                                   stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)  # fmt: skip
        _, status, usage = os.wait4(process.pid, 0)
        took = time.perf_counter() - started
        process.returncode = os.waitstatus_to_exitcode(status)
        if process.returncode != 0:
            error = process.stderr.read().decode() if process.stderr else ""
            raise RuntimeError(f"{name} failed at {tree}:\n{error[-2000:]}")
        if process.stderr:
            process.stderr.close()
        return took, usage.ru_maxrss * 1024


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--against", metavar="REV", help="REV's first starts beside this tree's")
    parser.add_argument("--only", choices=sorted(STARTS), help="one start only")
    args = parser.parse_args(argv)
    names = [args.only] if args.only else list(STARTS)
    trees = [(args.against, worktree(args.against))] if args.against else []
    trees.append(("this tree", REPO))
    print("First start from an empty compile cache (wall s, peak resident GB), a process each:")
    header = "".join(f"{label[:12]:>22}" for label, _ in trees)
    print(f"  {'start':18}{header}")
    verdicts = []
    for name in names:
        cells = []
        for label, tree in trees:
            took, peak = first_start(tree, name)
            cells.append(f"{took:9.1f} s {peak / 1e9:6.2f} GB")
            if label == "this tree":
                verdicts.append((name, took, peak))
        print(f"  {name:18}" + "".join(f"{cell:>22}" for cell in cells), flush=True)
    for name, took, peak in verdicts:
        ok = took <= TARGET_S and peak <= TARGET_BYTES
        print(f"{'meets' if ok else 'BELOW'} target: {name}, {took:.1f} s and {peak / 1e9:.2f} GB "
              f"vs {TARGET_S:.0f} s and {TARGET_BYTES / 1e9:.1f} GB")  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
