"""benchmarks/vmas_beside.py runs end to end and prints NanoNav's rows (and VMAS's, where VMAS
is installed; it is no dependency, so CI prints the line that says how to add it)."""

from __future__ import annotations

import importlib.util
import re
import subprocess
import sys
from pathlib import Path

import pytest

SCRIPT = Path(__file__).resolve().parents[2] / "benchmarks" / "vmas_beside.py"


@pytest.mark.timeout(300)
def test_the_vmas_comparison_prints_each_rate() -> None:
    done = subprocess.run(
        [sys.executable, str(SCRIPT), "--quick"], capture_output=True, text=True, timeout=280
    )
    assert done.returncode == 0, done.stderr
    rates = {
        label.strip(): float(rate.replace(",", ""))
        for label, rate in re.findall(r"^  (.+?)\s+([\d,]+)$", done.stdout, flags=re.M)
    }
    assert rates["NanoNav vector env, paper-single (lattice), 1 robot"] > 0
    assert rates["NanoNav vector env, tumour-microswimmers, 1 robot"] > 0
    if importlib.util.find_spec("vmas") is None:
        assert "VMAS is not installed (pip install vmas)" in done.stdout
    else:
        assert rates["VMAS navigation, 4 agent(s)"] > 0
        assert done.stdout.count("target:") == 2
