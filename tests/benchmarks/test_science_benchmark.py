"""The science report still runs end to end and prints its five tables (values not asserted
here: tests/engine/test_learning.py pins the claims)."""

import sys
from pathlib import Path

import pytest
from matplotlib.image import imread

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))

import science


def test_science_report_prints_every_section_and_writes_its_pictures(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert science.main(["--quick", "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    for heading in ("1. Defaults", "2. Chemotaxis", "3. Trained against untrained",
                    "4. Learned against fixed", "4b. What the learned behaviours do",
                    "5. authors-script"):  # fmt: skip
        assert heading in out, heading
    assert "paired" in out and "p=" in out and "simple_rule" in out and "seeds to resolve" in out
    for name in ("chemotaxis.png", "settings.png"):
        image = imread(tmp_path / name)
        assert image.shape[0] > 100 and image[..., :3].std() > 0.05
