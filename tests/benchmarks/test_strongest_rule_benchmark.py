"""benchmarks/strongest_rule.py runs and prints every candidate rule's success on the design
seeds, marks the one it chooses, and compares that choice on the report seeds with Holm's
adjustment (its figures live in the benchmark)."""

import re
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))

import strongest_rule


@pytest.mark.parametrize("preset", strongest_rule.PRESETS)
def test_the_choice_is_made_on_design_seeds_and_reported_on_others(
    preset: str, capsys: pytest.CaptureFixture[str]
) -> None:
    assert strongest_rule.main(["--quick", "--preset", preset]) == 0
    out = capsys.readouterr().out
    design, report = out.split("Report seeds", 1)
    rules = [strongest_rule.label(r) for r in strongest_rule.candidates(preset, quick=True)]
    shown = re.findall(r"^  (.+?)\s+\d\.\d\d \[\d\.\d\d, \d\.\d\d\]", design, re.M)
    blind = [strongest_rule.label(r) for r in strongest_rule.BLIND[:1]]
    assert shown == [*rules, *strongest_rule.BESIDE, *blind], out
    chosen = re.findall(r"^  (.+?)\s+\d\.\d\d \[\d\.\d\d, \d\.\d\d\]  <- chosen$", design, re.M)
    learns = any(r.startswith("q_learning") for r in rules)
    # the strongest fixed rule, and where learners were tried the best of them
    assert len(chosen) == 1 + learns and all(c in rules for c in chosen), out
    assert report.count("Report seeds") == 1  # the second report (split off above: two in all)
    for section in out.split("Report seeds")[1:]:
        holm = re.findall(r"^  (strongest rule - (?:plain gradient|uncontrolled|blind tumbler)|"
                          r"learner - strongest rule)\s+"
                          r"[+-]\d\.\d\d \[[+-]\d\.\d\d, [+-]\d\.\d\d\]\*? +Holm p ([\d.e-]+)$",
                          section, re.M)  # fmt: skip
        assert len(holm) == 3 + learns and all(0 <= float(p) <= 1 for _, p in holm), section
        assert f"Holm over {3 + learns} comparisons" in section
