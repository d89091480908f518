"""The service benchmark still runs end to end and prints measured figures (not asserted)."""

import importlib.util
import re
import sys
from pathlib import Path

import pytest

# Loaded from its path: the name ``service`` is the API package's.
_PATH = Path(__file__).resolve().parents[2] / "benchmarks" / "service.py"
_SPEC = importlib.util.spec_from_file_location("service_benchmark", _PATH)
assert _SPEC is not None and _SPEC.loader is not None
service_benchmark = importlib.util.module_from_spec(_SPEC)
sys.modules["service_benchmark"] = service_benchmark
_SPEC.loader.exec_module(service_benchmark)


def test_service_benchmark_prints_throughput_and_picture_times(
    capsys: pytest.CaptureFixture[str],
) -> None:
    assert service_benchmark.main(["--quick"]) == 0
    out = capsys.readouterr().out
    rate = re.search(r"^  ([\d.]+) jobs/s: ", out, re.M)
    assert rate is not None and float(rate.group(1)) > 0
    firsts = re.findall(r"^  first  (\S+)\s+([\d.]+) ms$", out, re.M)
    assert [path for path, _ in firsts] == list(service_benchmark.PICTURES)
    assert re.search(r"^  later  10 requests: p50 [\d.]+ ms", out, re.M)
    assert re.search(r"^study: .* \(6 jobs\)$", out, re.M)
