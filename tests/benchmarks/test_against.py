"""Old and new side by side: a measurement runs in a fresh process whose ``nanonav`` is the tree
it is asked of, this one or a revision checked out beside it."""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))

import against

# a stand-in for a benchmark: its figure says whether nanonav came from the tree named
SCRIPT = """
import sys
import nanonav
print(float(nanonav.__file__.startswith(sys.argv[2])))
"""


def test_a_measurement_imports_the_tree_it_is_asked_of(tmp_path: Path) -> None:
    script = tmp_path / "figure.py"
    script.write_text(SCRIPT)
    old = against.worktree("HEAD")
    assert (old / "nanonav" / "__init__.py").is_file()
    assert against.worktree("HEAD") == old  # made once
    assert against.measure(old, script, str(old)) == 1.0
    assert against.measure(against.REPO, script, str(against.REPO)) == 1.0
    assert against.measure(against.REPO, script, str(old)) == 0.0
