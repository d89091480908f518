"""The dashboard benchmark still runs and prints paint times (not asserted: a benchmark)."""

import re
import sys
from pathlib import Path

import pytest

from tests.browser.conftest import CHROMIUM, require_chromium

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))

import dashboard


def test_dashboard_benchmark_prints_paint_times(capsys: pytest.CaptureFixture[str]) -> None:
    require_chromium()
    assert dashboard.main(["--visits", "1", "--study-seeds", "2", "--chromium", CHROMIUM]) == 0
    out = capsys.readouterr().out
    found = re.findall(r"first contentful paint (\d+) ms", out)
    assert len(found) == 2 and all(int(ms) > 0 for ms in found)
    assert "study page (4 jobs)" in out
