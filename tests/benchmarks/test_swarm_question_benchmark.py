"""The swarm's question runs end to end on seeds of one's own, and ends with each family of
comparisons after Holm's adjustment (values not asserted here: tests/engine pins the swarm)."""

import re
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))

import swarm_question


def test_the_swarms_question_counts_each_family(capsys: pytest.CaptureFixture[str]) -> None:
    assert swarm_question.main(["--quick", "--seeds-from", "40"]) == 0
    out = capsys.readouterr().out
    assert "2 seeds x 1 worlds" in out
    # quick: 3 cells x 2 swarms x 3 models against none; 4 learners against the rule
    found = r"^(.+): (\d+) comparisons; resolved after Holm's adjustment:$"
    families = re.findall(found, out, re.M)
    assert families == [("treated minus none", "18"), ("steps minus none", "18"),
                        ("q_learning minus rule", "4")]  # fmt: skip
