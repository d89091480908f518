"""The transition band's script trains in stages that resume, adds a curve point a stage, and
reports every run against the rule with Holm, and its curves as a PNG (values not asserted:
the learners train for seconds here)."""

import json
import re
import sys
from pathlib import Path

import pytest
from matplotlib import image

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))

import transition_band


def test_a_smoke_run_trains_both_learners_and_reports_them(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert transition_band.main(["--quick", "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    for learner in transition_band.LEARNERS:
        points = json.loads((tmp_path / f"1-um-{learner}" / "curve.json").read_text())
        decisions = [p["decisions"] for p in points]
        assert len(decisions) == 2 and decisions[0] < decisions[1], points
        assert all(0.0 <= p["success"] <= 1.0 for p in points)
        pattern = rf"^  R = 1 um  rule .* {learner} - rule [+-]\d\.\d\d \[.*Holm"
        rows = re.findall(pattern, out, re.M)
        assert len(rows) == 2, out  # one a seed set
    # what each learner chose, by action, its shares summing to 1
    made = re.findall(r"^    its decisions: keep_heading ([\d.]+), steer_up_gradient ([\d.]+), "
                      r"tumble ([\d.]+), steer_to_cell ([\d.]+)$", out, re.M)  # fmt: skip
    assert len(made) == 2 * len(transition_band.LEARNERS), out
    assert all(abs(sum(float(x) for x in row) - 1.0) < 0.02 for row in made)
    assert f"Holm over the {len(transition_band.LEARNERS)} comparisons of this set" in out
    # what each steers by: its network replayed outside the sandbox makes the same decisions,
    # and each observation shuffled in turn changes a share of them
    reads = re.findall(r"^    what it reads: replay agrees with the sandbox in ([\d.]+) of [\d,]+; "
                       r"reading shuffled: ([\d.]+) .*; reading_change shuffled: ([\d.]+) .*; "
                       r"obstacle shuffled: ([\d.]+) ", out, re.M)  # fmt: skip
    assert len(reads) == len(transition_band.LEARNERS), out  # the first seed set only
    assert all(float(row[0]) == 1.0 for row in reads), reads
    assert all(0.0 <= float(x) <= 1.0 for row in reads for x in row[1:])
    # and a second look: the same networks sampling their actions as in training
    sampled = re.findall(r"^    sampled as trained: .* minus the rule [+-]\d\.\d\d \[.*\] p .* "
                         r"\(not in the Holm family\)$", out, re.M)  # fmt: skip
    assert len(sampled) == 2 * len(transition_band.LEARNERS), out
    picture = image.imread(tmp_path / "curves.png")
    assert picture.shape[0] > 100 and picture.shape[1] > 100


def test_a_run_given_again_goes_on_from_its_checkpoint(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    batch = transition_band.config("mlp", True).batch
    first = transition_band.train(1.0, "mlp", batch, tmp_path, (1, 1), quick=True)
    again = transition_band.train(1.0, "mlp", batch, tmp_path, (1, 1), quick=True)
    assert [p["decisions"] for p in again] == [p["decisions"] for p in first] == [batch]
    longer = transition_band.train(1.0, "mlp", 3 * batch, tmp_path, (1, 1), quick=True)
    assert [p["decisions"] for p in longer] == [batch, 2 * batch, 3 * batch]
