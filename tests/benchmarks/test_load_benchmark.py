"""The load benchmark still runs end to end, and every request it sends is answered."""

import importlib.util
import re
import sys
from pathlib import Path

import pytest

_PATH = Path(__file__).resolve().parents[2] / "benchmarks" / "load.py"
_SPEC = importlib.util.spec_from_file_location("load_benchmark", _PATH)
assert _SPEC is not None and _SPEC.loader is not None
load_benchmark = importlib.util.module_from_spec(_SPEC)
sys.modules["load_benchmark"] = load_benchmark
_SPEC.loader.exec_module(load_benchmark)


def test_load_benchmark_prints_rates_and_latencies_without_errors(
    capsys: pytest.CaptureFixture[str],
) -> None:
    assert load_benchmark.main(["--duration", "4", "--clients", "4", "--max-requests", "400"]) == 0
    out = capsys.readouterr().out
    rate = re.search(r"^  ([\d.]+) requests/s \((\d+) answered\), (\d+) jobs ended$", out, re.M)
    assert rate is not None and float(rate.group(1)) > 0 and int(rate.group(2)) <= 400, out
    for route in ("POST /jobs", "GET /jobs/{id}"):
        line = re.search(rf"^  {re.escape(route)} +n +(\d+) +p50 ([\d.]+) ms +p99 ([\d.]+) ms",
                         out, re.M)  # fmt: skip
        assert line is not None and int(line.group(1)) > 0, out
        assert 0 < float(line.group(2)) <= float(line.group(3))
    cores = re.search(r"^  cores busy on average, of \d+: API ([\d.]+), workers ([\d.]+), "
                      r"clients ([\d.]+)$", out, re.M)  # fmt: skip
    assert cores is not None and all(float(share) > 0 for share in cores.groups()), out
    assert re.search(r"^  errors: 0$", out, re.M), out
