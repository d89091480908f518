"""The load benchmark still runs end to end, and every request it sends is answered."""

import re
import sys
from pathlib import Path

import pytest

# Imported by its own name from its directory, as the client processes it spawns import it.
sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))

import load as load_benchmark


def test_clients_in_one_process_count_what_they_send_and_see() -> None:
    with load_benchmark.null_service() as service:
        tally, elapsed, cpu = load_benchmark.drive(service.url, 3, 1, 2.0, 0.1, 60)
    answered = sum(len(times) for times in tally.times.values())
    assert 0 < answered <= tally.sent <= 60 and not tally.errors
    assert len(tally.times["POST /jobs"]) >= 3 and tally.times["GET /jobs/{id}"]
    assert all(0 < t < 30 for times in tally.times.values() for t in times)
    assert 0 < elapsed < 30 and cpu > 0


def test_load_benchmark_prints_rates_latencies_and_its_floor_without_errors(
    capsys: pytest.CaptureFixture[str],
) -> None:
    argv = ["--duration", "3", "--clients", "4", "--client-processes", "2", "--floor",
            "--max-requests", "200"]  # fmt: skip
    assert load_benchmark.main(argv) == 0
    out = capsys.readouterr().out
    floor, _, real = out.partition("\nload: ")
    assert floor.startswith("floor: 4 clients in 2 process(es) for "), out
    assert "on a server that does nothing" in floor.splitlines()[0]
    assert real.startswith("4 clients in 2 process(es) for "), out
    for part in (floor, real):
        rate = re.search(r"^  ([\d.]+) requests/s \((\d+) answered\), (\d+) jobs ended$", part,
                         re.M)  # fmt: skip
        # each process stops at its half of the cap
        assert rate is not None and float(rate.group(1)) > 0 and int(rate.group(2)) <= 200, out
        assert int(rate.group(3)) > 0, out
        for route in ("POST /jobs", "GET /jobs/{id}"):
            line = re.search(rf"^  {re.escape(route)} +n +(\d+) +p50 ([\d.]+) ms +p99 ([\d.]+) ms",
                             part, re.M)  # fmt: skip
            assert line is not None and int(line.group(1)) > 0, out
            assert 0 < float(line.group(2)) <= float(line.group(3))
        assert re.search(r"^  errors: 0$", part, re.M), out
    assert re.search(r"^  cores busy on average, of \d+: API [\d.]+, clients [\d.]+$",
                     floor, re.M), out  # fmt: skip
    cores = re.search(r"^  cores busy on average, of \d+: API ([\d.]+), workers ([\d.]+), "
                      r"clients ([\d.]+)$", real, re.M)  # fmt: skip
    assert cores is not None and all(float(share) > 0 for share in cores.groups()), out


def test_load_benchmark_refuses_more_client_processes_than_clients() -> None:
    with pytest.raises(SystemExit) as refused:
        load_benchmark.main(["--clients", "2", "--client-processes", "3"])
    assert refused.value.code == 2
