"""benchmarks/strongest_rule.py runs and prints every candidate rule's success on the design
seeds, marks the one it chooses, and compares that choice on the report seeds with Holm's
adjustment (its figures live in the benchmark)."""

import re
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))

import strongest_rule


def test_the_choice_is_made_on_design_seeds_and_reported_on_others(
    capsys: pytest.CaptureFixture[str],
) -> None:
    assert strongest_rule.main(["--quick"]) == 0
    out = capsys.readouterr().out
    design, report = out.split("Report seeds")
    candidates = re.findall(r"^  ((?:gradient|steer_and_tumble), memory [\d.]+ s, turn [\d.]+ "
                            r"rad/s)\s+\d\.\d\d \[\d\.\d\d, \d\.\d\d\]", design, re.M)  # fmt: skip
    assert len(candidates) == len(strongest_rule.candidates(quick=True)) == 8
    chosen = re.findall(r"^  (.+?)\s+\d\.\d\d \[\d\.\d\d, \d\.\d\d\]  <- chosen$", design, re.M)
    assert len(chosen) == 1 and chosen[0] in candidates
    assert f"radius 2 um: chosen {chosen[0]}" in report
    holm = re.findall(r"chosen - .+ [+-]\d\.\d\d \[[+-]\d\.\d\d, [+-]\d\.\d\d\]\*? +Holm p "
                      r"([\d.e-]+)$", report, re.M)  # fmt: skip
    assert len(holm) == 2 and all(0 <= float(p) <= 1 for p in holm)
    assert "Holm over 2 comparisons" in report
