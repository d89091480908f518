"""The ``nanonav`` command: ``run`` in-process through ``main`` and once as a real process."""

import io
import json
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from matplotlib.image import imread

import nanonav.engine
from nanonav import cli
from nanonav.engine import Progress, SimulationResult, simulate
from nanonav.pictures import job as pictures

SMALL: dict[str, Any] = {"learning": {"episodes": 2, "max_steps": 200}, "obstacles": {"count": 3}}
DOCUMENT_KEYS = {
    "scenario", "completed", "summary", "uncertainty", "worlds", "robots", "episodes", "work"
}  # fmt: skip
TABLE_ROWS = (
    "Total Steps",
    "Final Distance",
    "Average Distance",
    "Average Biomarker Concentration",
    "Computing Time per World",
    "Success Rate",
    "Collisions",
    "Path Efficiency",
)


def write_scenario(tmp_path: Path, data: Any, name: str = "scenario.json") -> str:
    path = tmp_path / name
    path.write_text(json.dumps(data), encoding="utf-8")
    return str(path)


def without_compiling(err: str) -> str:
    """``err`` without the line a run prints where the engine is not yet compiled here."""
    return "".join(line for line in err.splitlines(keepends=True)
                   if not line.startswith("nanonav run: compiling the engine"))  # fmt: skip


def test_json_prints_one_document_with_the_resolved_seed(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = write_scenario(tmp_path, {**SMALL, "seed": 3, "robots": {"count": 4}})
    args = ["run", "--scenario", path, "--preset", "paper-swarm", "--seed", "7", "--json"]
    assert cli.main(args) == 0  # the engine compiled here, if it was not yet
    capsys.readouterr()
    code = cli.main(args)
    out, err = capsys.readouterr()
    assert code == 0
    document = json.loads(out)
    assert set(document) == DOCUMENT_KEYS
    assert document["completed"] is True
    assert document["scenario"]["seed"] == 7
    assert document["scenario"]["preset"] == "paper-swarm"
    assert document["scenario"]["robots"]["count"] == 4  # the file's field beats the preset
    assert document["scenario"]["cells"]["count"] == 2  # the preset fills the rest
    assert len(document["robots"]) == 4
    assert len(document["episodes"]) == 2
    assert err == ""


def test_text_output_is_table_1_with_a_row_per_robot_for_a_swarm(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = write_scenario(tmp_path, {**SMALL, "robots": {"count": 3}})
    assert cli.main(["run", "--scenario", path, "--seed", "1"]) == 0
    out = capsys.readouterr().out
    lines = out.splitlines()
    assert lines[0].startswith("Table 1: custom scenario, seed 1, 3 robots")
    for row in TABLE_ROWS:
        assert any(line.startswith(row) for line in lines), row
    assert "Per robot (the first evaluation world):" in lines
    robot_rows = [line.split() for line in lines if line.split()[:1] in (["0"], ["1"], ["2"])]
    assert [row[0] for row in robot_rows] == ["0", "1", "2"]


def test_single_robot_table_has_no_per_robot_rows(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = write_scenario(tmp_path, SMALL)
    assert cli.main(["run", "--scenario", path, "--preset", "paper-single"]) == 0
    out = capsys.readouterr().out
    assert out.startswith("Table 1: paper-single, seed 0, 1 robot, 1 cell")
    assert "Per robot" not in out


def test_out_writes_decodable_pictures_arrays_and_metrics(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = write_scenario(tmp_path, {**SMALL, "robots": {"count": 2}})
    out_dir = tmp_path / "results" / "run1"
    assert cli.main(["run", "--scenario", path, "--out", str(out_dir), "--json"]) == 0
    printed = json.loads(capsys.readouterr().out)
    assert not (out_dir / "treatment.png").exists()  # only a swarm's run has it
    for name in (n for n in pictures.PICTURE_NAMES if n != "treatment"):
        png = (out_dir / f"{name}.png").read_bytes()
        assert png.startswith(b"\x89PNG\r\n\x1a\n")
        assert imread(io.BytesIO(png), format="png").ndim == 3
    with np.load(out_dir / "result.npz") as arrays:
        assert arrays["robots"].shape[1:] == (2, 3)
        assert arrays["robot_steps"].shape == (2,)
        assert "q_values" in arrays
    metrics = json.loads((out_dir / "metrics.json").read_text(encoding="utf-8"))
    assert metrics["scenario"] == printed["scenario"]
    assert metrics["robots"] == printed["robots"]


def test_out_writes_the_qtable_picture_only_for_a_policy_that_learns_a_table(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    learner = write_scenario(tmp_path, SMALL)
    baseline = write_scenario(
        tmp_path, {**SMALL, "robots": {"policy": "gradient"}}, "gradient.json"
    )
    assert cli.main(["run", "--scenario", learner, "--out", str(tmp_path / "learner")]) == 0
    assert cli.main(["run", "--scenario", baseline, "--out", str(tmp_path / "gradient")]) == 0
    capsys.readouterr()
    table = imread(tmp_path / "learner" / "qtable.png", format="png")
    assert table.shape[:2] == (1500, 830)  # 72 states x 4 actions, as the service draws it
    assert not (tmp_path / "gradient" / "qtable.png").exists()
    assert (tmp_path / "gradient" / "learning.png").exists()


def test_invalid_scenario_exits_2_naming_each_field(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = write_scenario(tmp_path, {"robots": {"count": 200_000}, "learning": {"alpha": 0}})
    assert cli.main(["run", "--scenario", path]) == 2
    out, err = capsys.readouterr()
    assert out == ""
    assert err.splitlines() == [
        "nanonav run: robots.count: Input should be less than or equal to 100000",
        "nanonav run: learning.alpha: Input should be greater than 0",
    ]


def test_unknown_key_is_rejected(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = write_scenario(tmp_path, {"robots": {"colour": "blue"}, "speed": 2})
    assert cli.main(["run", "--scenario", path, "--json"]) == 2
    out, err = capsys.readouterr()
    assert out == ""
    assert "nanonav run: robots.colour: Extra inputs are not permitted" in err
    assert "nanonav run: speed: Extra inputs are not permitted" in err


def test_a_rule_across_fields_names_the_field_at_fault(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = write_scenario(tmp_path, {"learning": {"epsilon_start": 0.1, "epsilon_end": 0.5}})
    assert cli.main(["run", "--scenario", path]) == 2
    assert "learning.epsilon_end: must not exceed epsilon_start" in capsys.readouterr().err


def test_a_scenario_that_evaluates_a_jobs_table_is_sent_to_the_service(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = write_scenario(tmp_path, {"policy_from": 4, "learning": {"episodes": 0}})
    assert cli.main(["run", "--scenario", path]) == 2
    assert "policy_from: job 4 is a job of the service" in capsys.readouterr().err


def test_a_world_with_no_room_for_its_obstacles_is_a_usage_error(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    crowded = {
        "robots": {"count": 10000},
        "obstacles": {"count": 300, "radius": 3.0},
        "learning": {"episodes": 0, "max_steps": 5},
    }
    assert cli.main(["run", "--scenario", write_scenario(tmp_path, crowded)]) == 2
    assert "obstacles.count: could not place obstacle" in capsys.readouterr().err


@pytest.mark.parametrize(
    ("content", "message"),
    [
        ('{"seed": ', "invalid JSON at line 1 column 10"),
        ("[1, 2]", "the scenario must be a JSON object"),
    ],
)
def test_malformed_file_exits_2_with_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], content: str, message: str
) -> None:
    path = tmp_path / "broken.json"
    path.write_text(content, encoding="utf-8")
    assert cli.main(["run", "--scenario", str(path)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1
    assert message in err


def test_missing_file_exits_2(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert cli.main(["run", "--scenario", str(tmp_path / "absent.json")]) == 2
    assert "cannot read" in capsys.readouterr().err


def test_unknown_preset_and_negative_seed_exit_2(capsys: pytest.CaptureFixture[str]) -> None:
    assert cli.main(["run", "--preset", "paper-huge"]) == 2
    assert "invalid choice: 'paper-huge'" in capsys.readouterr().err
    assert cli.main(["run", "--seed", "-1"]) == 2
    assert "nanonav run: seed: Input should be greater than or equal to 0" in (
        capsys.readouterr().err
    )


def test_help_lists_run_and_exits_0(capsys: pytest.CaptureFixture[str]) -> None:
    assert cli.main(["--help"]) == 0
    assert "run" in capsys.readouterr().out
    assert cli.main([]) == 2


def test_ctrl_c_stops_the_run_cleanly_with_exit_130(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """The real engine runs; a SIGINT arrives at its first progress report."""
    finished: list[bool] = []
    reports: list[Progress] = []

    def simulate_then_press_ctrl_c(scenario: Any, progress: Any) -> SimulationResult:
        def interrupted(state: Progress) -> bool | None:
            if not reports:
                signal.raise_signal(signal.SIGINT)
            reports.append(state)
            answer: bool | None = progress(state)
            return answer

        result = simulate(scenario, interrupted)
        finished.append(result.completed)
        return result

    monkeypatch.setattr(nanonav.engine, "simulate", simulate_then_press_ctrl_c)
    path = write_scenario(tmp_path, {"learning": {"episodes": 50, "max_steps": 100}})
    before = signal.getsignal(signal.SIGINT)
    assert cli.main(["run", "--scenario", path, "--json", "--out", str(tmp_path / "o")]) == 130
    out, err = capsys.readouterr()
    assert finished == [False]
    assert out == ""
    assert without_compiling(err) == "nanonav run: interrupted\n"
    assert not (tmp_path / "o").exists()
    assert signal.getsignal(signal.SIGINT) is before


def test_command_runs_as_a_process(tmp_path: Path) -> None:
    path = write_scenario(tmp_path, SMALL)
    completed = subprocess.run(
        [sys.executable, "-m", "nanonav.cli", "run", "--scenario", path, "--seed", "9", "--json"],
        capture_output=True,
        text=True,
        timeout=240,
        check=False,
    )
    assert completed.returncode == 0, completed.stderr
    document = json.loads(completed.stdout)
    assert set(document) == DOCUMENT_KEYS
    assert document["scenario"]["seed"] == 9
    # nothing on stderr but, where the engine was not yet compiled here, the line saying so
    said = completed.stderr.splitlines()
    assert said == [] or (len(said) == 1 and "compiling the engine" in said[0]), said


def test_a_physical_preset_runs_and_prints_its_units(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    physics = {"model": "active_brownian", "time_limit_s": 1.0}
    scenario = {
        "physics": physics,
        "robots": {"count": 3},
        "learning": {"episodes": 1},
        "evaluation": {"worlds": 1},
    }
    path = write_scenario(tmp_path, scenario)
    out_dir = tmp_path / "out"
    code = cli.main(
        [
            "run",
            "--scenario",
            path,
            "--preset",
            "tumour-microswimmers",
            "--seed",
            "2",
            "--out",
            str(out_dir),
        ]
    )
    out = capsys.readouterr().out
    assert code == 0
    assert "Total Steps (of 0.01 s)" in out and "1 training episode," in out
    assert "um" not in out.split() and "(um)" not in out
    lines = out.splitlines()
    distance = next(line for line in lines if line.startswith("Final Distance"))
    assert re.search(r"\d\.\d\d µm", distance)
    concentration = next(line for line in lines if line.startswith("Average Biomarker"))
    # three significant figures and the unit, never a bare 0.00
    assert re.search(r"\d(\.\d+)?(e-\d+)? nM", concentration)
    robots = lines[lines.index("Per robot (the first evaluation world):") + 3 :][:3]
    assert all(" nM" in row and " µm" in row for row in robots)
    assert not any(" 0.00 " in row.split("µm")[-1] for row in robots)
    document = json.loads((out_dir / "metrics.json").read_text(encoding="utf-8"))
    assert document["physics"]["time_limit_s"] == pytest.approx(1.0)
    with np.load(out_dir / "result.npz") as arrays:
        assert arrays["headings"].shape[1:] == (3, 3) and arrays["sensed"].shape[1] == 3


def test_set_overrides_a_field_as_submit_does(capsys: pytest.CaptureFixture[str]) -> None:
    code = cli.main(["run", "--preset", "paper-single", "--set", "learning.episodes=2",
                     "--set", "learning.max_steps=50", "--json"])  # fmt: skip
    out, _ = capsys.readouterr()
    assert code == 0
    document = json.loads(out)
    assert document["scenario"]["learning"]["episodes"] == 2
    assert document["scenario"]["learning"]["max_steps"] == 50
    assert len(document["episodes"]) == 2


def test_a_set_the_scenario_refuses_names_the_field(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    code = cli.main(["run", "--preset", "paper-single", "--set", "robots.count=many"])
    assert code == 2
    assert capsys.readouterr().err.startswith("nanonav run: robots.count: ")
    path = write_scenario(tmp_path, {"seed": 3})
    code = cli.main(["run", "--scenario", path, "--set", "seed.x=1"])
    assert code == 2
    assert "--set seed.x: seed is not a section" in capsys.readouterr().err


def test_an_argument_run_does_not_know_is_said_with_runs_usage(
    capsys: pytest.CaptureFixture[str],
) -> None:
    code = cli.main(["run", "--preset", "paper-single", "--episodes", "2"])
    err = capsys.readouterr().err
    assert code == 2
    assert err.startswith("usage: nanonav run ")
    assert "nanonav run: error: unrecognized arguments: --episodes 2" in err
    assert "COMMAND" not in err  # not the top level's usage


def test_a_cold_run_says_it_is_compiling_before_it_compiles(tmp_path: Path) -> None:
    """With no machine code on disk (an empty ``NUMBA_CACHE_DIR``), the first line comes at
    once, not after the minute of compiling it announces (the process is stopped then)."""
    cold = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "empty")}
    started = time.monotonic()
    process = subprocess.Popen(
        [sys.executable, "-m", "nanonav.cli", "run", "--preset", "paper-single", "--set",
         "learning.episodes=1", "--json"],
        stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, env=cold,
    )  # fmt: skip
    try:
        assert process.stderr is not None
        first = process.stderr.readline()
        said_after_s = time.monotonic() - started
        assert first.startswith("nanonav run: compiling the engine for this machine"), first
        assert process.poll() is None, "it had finished: the line came after the compile"
    finally:
        process.kill()
        process.communicate()
    assert said_after_s < 30.0  # a second or two idle; the bound only rules out the compile
