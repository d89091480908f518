"""The engine's plain data is read without its compiled code: a process that imports only the
labels, the tables of states and the metrics' ranges (as the API's schemas do) loads no numba,
and every public name of the engine is still found where ``nanonav.engine`` says."""

from __future__ import annotations

import importlib
import subprocess
import sys

import nanonav.engine as engine


def test_the_engines_plain_data_loads_no_numba() -> None:
    code = (
        "import sys\n"
        "import nanonav.engine.observations, nanonav.engine.qlearning, nanonav.engine.metrics\n"
        "assert 'numba' not in sys.modules, sorted(m for m in sys.modules if 'numba' in m)[:5]\n"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=False)
    assert done.returncode == 0, done.stderr


def test_every_public_name_of_the_engine_is_found_in_its_module() -> None:
    assert sorted(engine._HOMES) == sorted(engine.__all__)
    for name, home in engine._HOMES.items():
        module = importlib.import_module(f"nanonav.engine.{home}")
        assert getattr(engine, name) is getattr(module, name)
