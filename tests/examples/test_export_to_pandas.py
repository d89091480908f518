"""The export-to-pandas guide's code runs as printed against a real service whose study 1 and
job 1 are what the guide reads, and gives the tables it says."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import httpx
import pytest

from tests.conftest import api_and_worker
from tests.processes import clean_environment

pytestmark = pytest.mark.timeout(300)

PAGE = Path(__file__).resolve().parents[2] / "docs/how-to/export-to-pandas.md"
STUDY = {
    "base": {"preset": "paper-single", "learning": {"episodes": 3}, "evaluation": {"worlds": 2}},
    "grid": {"robots.policy": ["q_learning", "gradient"]},
    "seeds": [0, 1, 2],
    "compare": "robots.policy",
}
CHECKS = """
assert list(steps.columns) == ["gradient", "q_learning"] and len(steps) == 3
assert len(robots) == 1 and len(worlds) == 2 and curve.index.name == "episode"
assert set(paths["kind"]) == {"robot", "cell", "obstacle"}, set(paths["kind"])
assert len(robot_0) > 1, len(robot_0)
assert frame.shape == arrays["distance"].shape, (frame.shape, arrays["distance"].shape)
assert frame.columns[0] == "robot_0", list(frame.columns)
assert values.shape == (len(q["states"]), len(q["actions"])) and greedy.index.name == "state"
print("checked")
"""


def guide_code(url: str) -> str:
    blocks = re.findall(r"^```python\n(.*?)^```$", PAGE.read_text(), flags=re.DOTALL | re.M)
    assert len(blocks) == 6
    return "\n".join(blocks).replace("http://127.0.0.1:8000", url)


def test_the_guides_code_reads_a_study_a_jobs_metrics_trajectory_and_table(
    tmp_path: Path,
) -> None:
    with api_and_worker(tmp_path / "service") as (api, _, _):
        created = httpx.post(f"{api.url}/studies", json=STUDY, timeout=30)
        assert created.status_code == 202 and created.json()["id"] == 1
        done = subprocess.run(
            [sys.executable, "-c", "from nanonav.client import Client\n"
             "with Client() as api: assert api.wait_study(1, timeout_s=240).status == 'succeeded'"],
            env=clean_environment(NANONAV_URL=api.url), capture_output=True, text=True,
            timeout=280,
        )  # fmt: skip
        assert done.returncode == 0, done.stderr
        ran = subprocess.run(
            [sys.executable, "-c", guide_code(api.url) + CHECKS],
            env=clean_environment(NANONAV_URL=api.url),
            capture_output=True,
            text=True,
            timeout=120,
        )
    assert ran.returncode == 0, ran.stderr
    assert ran.stdout.rstrip().endswith("checked")
