"""``nanonav submit``, ``study``, ``fetch`` and ``jobs`` against a real API process and a real
worker process: in-process through ``main``, and as real processes for the exit codes, the
streams and Ctrl-C."""

from __future__ import annotations

import io
import json
import re
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from types import SimpleNamespace
from typing import Any, cast

import ase.io
import numpy as np
import pyarrow.parquet as pq
import pytest
from matplotlib.image import imread

from nanonav.cli import main
from nanonav.client import JOB_PICTURES, SWARM_PICTURES, Client, Job, Policy, Study
from nanonav.engine import qlearning
from tests.client.test_client import CROWDED, LONG, STUDY, TINY
from tests.conftest import LiveApi
from tests.processes import clean_environment, free_port

pytestmark = pytest.mark.timeout(180)
WAIT_S = 60.0
TABLE_1 = (
    "Total Steps", "Final Distance", "Average Distance", "Average Biomarker Concentration",
    "Computing Time per World", "Success Rate", "Collisions", "Path Efficiency",
)  # fmt: skip


@pytest.fixture
def api(live_api: LiveApi) -> Iterator[Client]:
    with Client(live_api.url, timeout=10) as client:
        yield client


@pytest.fixture(scope="module")
def finished(live_api: LiveApi) -> Iterator[tuple[Job, Study]]:
    """A succeeded job and a succeeded study, for the commands that read them."""
    with Client(live_api.url, timeout=10) as client:
        job = client.wait(client.submit({**TINY, "seed": 21}).id, poll_s=0.05, timeout_s=WAIT_S)
        study = client.wait_study(client.submit_study(STUDY).id, poll_s=0.1, timeout_s=WAIT_S)
        assert job.status == study.status == "succeeded"
        yield job, study


def write(tmp_path: Path, data: Any, name: str = "input.json") -> str:
    path = tmp_path / name
    path.write_text(json.dumps(data), encoding="utf-8")
    return str(path)


def submitted_id(out: str) -> int:
    found = re.match(r"job (\d+) queued \(seed \d+\)\n", out)
    assert found, out
    return int(found.group(1))


# ---------------------------------------------------------------- submit


def test_submit_wait_prints_the_id_then_table_1(
    live_api: LiveApi, tmp_path: Path, capsys: pytest.CaptureFixture[str], api: Client
) -> None:
    path = write(tmp_path, TINY)
    code = main(["submit", path, "--seed", "11", "--wait", "--url", live_api.url])
    out, err = capsys.readouterr()
    assert code == 0, err
    assert err == ""  # no bar: stderr is not a terminal
    job = api.job(submitted_id(out))
    assert job.status == "succeeded" and job.scenario["seed"] == 11
    lines = out.splitlines()
    assert lines[0] == f"job {job.id} queued (seed 11)"
    assert lines[2].startswith("Table 1: custom scenario, seed 11, 2 robots, 1 cell, q_learning")
    summary = api.metrics(job.id)["summary"]
    (steps,) = [line for line in lines if line.startswith("Total Steps")]
    assert steps.split()[2] == f"{summary['total_steps']:.2f}"
    for row in TABLE_1:
        assert any(line.startswith(row) for line in lines), row
    assert "Per robot (the first evaluation world):" in lines


def test_submit_a_preset_without_waiting_prints_the_id(
    live_api: LiveApi, capsys: pytest.CaptureFixture[str], api: Client
) -> None:
    code = main(["submit", "--preset", "paper-single", "--seed", "4", "--url", live_api.url])
    out, err = capsys.readouterr()
    assert (code, err) == (0, "")
    job = api.job(submitted_id(out))
    assert out == f"job {job.id} queued (seed 4)\n"
    assert job.scenario["preset"] == "paper-single" and job.scenario["obstacles"]["count"] == 10


def test_submit_of_a_job_that_fails_exits_1_with_its_error(
    live_api: LiveApi, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    code = main(["submit", write(tmp_path, CROWDED), "--wait", "--url", live_api.url])
    out, err = capsys.readouterr()
    assert code == 1
    job_id = submitted_id(out)
    assert err.startswith(f"nanonav submit: job {job_id} failed: ")
    assert "could not place obstacle" in err
    assert "Table 1" not in out


def test_an_invalid_scenario_exits_2_naming_each_field(
    live_api: LiveApi, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = write(tmp_path, {"robots": {"count": 0}, "learning": {"alpha": 0}})
    assert main(["submit", path, "--url", live_api.url]) == 2
    out, err = capsys.readouterr()
    assert out == ""
    assert err.splitlines() == [
        "nanonav submit: 422 Invalid input: #/robots/count: Input should be greater than or "
        "equal to 1",
        "nanonav submit:   #/robots/count: Input should be greater than or equal to 1",
        "nanonav submit:   #/learning/alpha: Input should be greater than 0",
    ]


def test_submit_needs_a_file_or_a_preset(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["submit", "--url", "http://127.0.0.1:1"]) == 2
    assert capsys.readouterr().err == "nanonav submit: give a scenario FILE or --preset NAME\n"
    assert main(["submit", "--preset", "x", "--url", "http://127.0.0.1:1"]) == 2
    assert "invalid choice: 'x'" in capsys.readouterr().err
    assert main(["submit", "--preset", "paper-single", "--url", "127.0.0.1:8000"]) == 2
    assert "not an http:// or https:// URL" in capsys.readouterr().err


# ---------------------------------------------------------------- study


def test_study_wait_prints_intervals_paired_differences_and_failures(
    live_api: LiveApi, tmp_path: Path, capsys: pytest.CaptureFixture[str], api: Client
) -> None:
    spec = {**STUDY, "seeds": [7, 8]}
    code = main(["study", write(tmp_path, spec), "--wait", "--url", live_api.url])
    out, err = capsys.readouterr()
    assert (code, err) == (0, "")
    # the suite's worker may have claimed a job before the answer was read
    found = re.match(r"study (\d+) (queued|running): 4 jobs \(2 grid points x 2 seeds\)\n", out)
    assert found, out
    study = api.study(int(found.group(1)))
    assert study.status == "succeeded"
    lines = out.splitlines()
    assert lines[2] == (
        f'Study {study.id} "two policies": succeeded, 4 jobs: 4 succeeded, 0 failed, 0 cancelled'
    )
    header = lines[4].split()
    assert header == ["robots.policy", "metric", "n", "mean", "95%", "CI"]
    rows = [line.split() for line in lines if line.split()[:2] in (
        ["q_learning", "total_steps"], ["gradient", "total_steps"]
    )]  # fmt: skip
    assert [row[0] for row in rows] == ["q_learning", "gradient"]
    for row, point in zip(rows, study.points, strict=True):
        interval = point.metrics["total_steps"]
        assert row[2] == "2"
        assert interval.mean is not None and float(row[3]) == pytest.approx(interval.mean, 1e-3)
        low, high = (float(x.strip("[],")) for x in row[4:6])
        # approx in a tuple: mypy's strict equality cannot see that it compares by its __eq__
        assert (low, high) == (  # type: ignore[comparison-overlap]
            pytest.approx(interval.ci_low, 1e-3),
            pytest.approx(interval.ci_high, 1e-3),
        )
    assert "Paired differences, seed by seed (robots.policy):" in lines
    (pair,) = [line.split() for line in lines if line.startswith("gradient - q_learning")]
    difference = study.comparisons[0].metrics[pair[3]]
    assert pair[:4] == ["gradient", "-", "q_learning", study.metrics[0]]
    assert pair[4] == "2"
    assert difference.mean_difference is not None
    assert float(pair[5]) == pytest.approx(difference.mean_difference, 1e-3, abs=1e-9)
    assert difference.p_value is not None and float(pair[-3]) == round(difference.p_value, 3)
    # one comparison of each metric: Holm's adjustment leaves it as it is
    assert difference.p_holm == difference.p_value and difference.holm_comparisons == 1
    assert float(pair[-2]) == round(difference.p_value, 3)
    # the smallest difference its two seeds resolve, from their spread
    assert difference.resolvable is not None
    assert float(pair[-1].replace(",", "")) == pytest.approx(difference.resolvable, 1e-3)
    assert lines[lines.index("Paired differences, seed by seed (robots.policy):") + 1].split()[
        -3:] == ["p", "Holm", "resolves"]  # fmt: skip
    assert any(line.startswith("resolves: the smallest mean difference") for line in lines)

    assert main(["study", "--id", str(study.id), "--url", live_api.url]) == 0
    shown = capsys.readouterr().out
    assert shown == "\n".join(lines[2:]) + "\n"


def test_a_study_with_a_failed_job_says_so_and_exits_1(
    live_api: LiveApi, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    grid = {"obstacles.count": [0, 300]}  # no room for 300
    spec = {"base": {**CROWDED, "obstacles": {"radius": 3.0}}, "grid": grid, "seeds": [1]}
    code = main(["study", write(tmp_path, spec), "--wait", "--url", live_api.url])
    out, err = capsys.readouterr()
    assert code == 1
    assert "2 jobs: 1 succeeded, 1 failed, 0 cancelled" in out
    assert "1 failed job left out of the means" in out
    assert re.fullmatch(
        r"nanonav study: study \d+ failed: 2 jobs: 1 succeeded, 1 failed, 0 cancelled\n", err
    )
    # retried in one command, the failed job runs again (and fails again: still no room)
    study_id = re.findall(r"study (\d+) failed", err)[0]
    code = main(["study", "--id", study_id, "--retry", "--wait", "--url", live_api.url])
    out, err = capsys.readouterr()
    assert code == 1
    assert out.startswith(f"study {study_id} running: 1 failed job queued again\n")
    assert "2 jobs: 1 succeeded, 1 failed, 0 cancelled" in out


def test_study_needs_a_file_or_an_id(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    assert main(["study", "--url", "http://127.0.0.1:1"]) == 2
    assert "give a study FILE to submit, or --id ID" in capsys.readouterr().err
    assert main(["study", write(tmp_path, {}), "--id", "3"]) == 2
    assert main(["study", "--id", "0"]) == 2
    assert "must be at least 1, not 0" in capsys.readouterr().err
    assert main(["study", write(tmp_path, {}), "--retry"]) == 2
    assert "--retry needs --id ID" in capsys.readouterr().err


# ---------------------------------------------------------------- fetch


def test_fetch_writes_a_jobs_results(
    live_api: LiveApi,
    finished: tuple[Job, Study],
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    api: Client,
) -> None:
    job, _ = finished
    out_dir = tmp_path / "made" / "here"
    assert main(["fetch", str(job.id), "--out", str(out_dir), "--url", live_api.url]) == 0
    out = capsys.readouterr().out
    drawn = [n for n in JOB_PICTURES if n not in SWARM_PICTURES]  # lone robots: no treatment
    names = ["metrics.json", "trajectory.npz", "trajectory.xyz", "qtable.json",
             *(f"{n}.png" for n in drawn)]  # fmt: skip
    assert sorted(p.name for p in out_dir.iterdir()) == sorted(names)
    lines = out.splitlines()
    assert lines[0] == f"Fetching job {job.id} into {out_dir}:"
    assert [line.split()[0] for line in lines[1:-1]] == names  # each said as it was written
    assert lines[-1] == f"Wrote {len(names)} files to {out_dir}"
    assert json.loads((out_dir / "metrics.json").read_text()) == api.metrics(job.id)
    assert json.loads((out_dir / "qtable.json").read_text()) == api.qtable(job.id)
    with np.load(out_dir / "trajectory.npz", allow_pickle=False) as arrays:
        assert arrays["robots"].shape[1:] == (2, 3)
        assert arrays["robot_steps"].tolist() == [
            r["total_steps"] for r in api.metrics(job.id)["robots"]
        ]
    for name in drawn:
        assert imread(out_dir / f"{name}.png", format="png").ndim == 3
    frames = ase.io.read(out_dir / "trajectory.xyz", index=":", format="extxyz")
    assert isinstance(frames, list)  # every frame, for index ":"
    with np.load(out_dir / "trajectory.npz", allow_pickle=False) as arrays:
        assert len(frames) == arrays["step"].shape[0]
        robots = [i for i, kind in enumerate(frames[-1].arrays["kind"]) if kind == "robot"]
        assert np.allclose(frames[-1].positions[robots], arrays["robots"][-1])


def test_fetch_of_a_swarm_job_writes_its_treatment_picture(
    live_api: LiveApi, tmp_path: Path, capsys: pytest.CaptureFixture[str], api: Client
) -> None:
    swarm = {**TINY, "robots": {"count": 3, "policy": "gradient"}, "cells": {"capacity": 1}}
    job = api.wait(api.submit(swarm).id)
    assert job.status == "succeeded"
    assert main(["fetch", str(job.id), "--out", str(tmp_path), "--url", live_api.url]) == 0
    assert imread(tmp_path / "treatment.png", format="png").ndim == 3


def test_fetch_of_a_baseline_job_writes_no_qtable(
    live_api: LiveApi, tmp_path: Path, capsys: pytest.CaptureFixture[str], api: Client
) -> None:
    job = api.wait(api.submit({**TINY, "robots": {"count": 1, "policy": "gradient"}}).id)
    assert job.status == "succeeded"
    assert main(["fetch", str(job.id), "--out", str(tmp_path), "--url", live_api.url]) == 0
    written = sorted(p.name for p in tmp_path.iterdir())
    assert "metrics.json" in written and "trajectory.png" in written
    assert "qtable.json" not in written and "qtable.png" not in written


def test_fetch_of_a_table_policy_writes_one_file_and_says_file(
    live_api: LiveApi, tmp_path: Path, capsys: pytest.CaptureFixture[str], api: Client
) -> None:
    states, actions = qlearning.labels("behaviors")
    policy = api.send_policy(states, actions, values=np.zeros((len(states), len(actions))))
    args = ["fetch", "--policy", str(policy.id), "--out", str(tmp_path), "--url", live_api.url]
    assert main(args) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[0] == f"Fetching policy {policy.id} into {tmp_path}:"
    assert [line.split()[0] for line in lines[1:-1]] == ["policy.json"]
    assert lines[-1] == f"Wrote 1 file to {tmp_path}"
    assert json.loads((tmp_path / "policy.json").read_text())["states"] == states


def test_fetch_writes_a_studys_table_and_pictures(
    live_api: LiveApi,
    finished: tuple[Job, Study],
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    api: Client,
) -> None:
    _, study = finished
    code = main(["fetch", "--study", str(study.id), "--out", str(tmp_path), "--url", live_api.url])
    out, err = capsys.readouterr()
    assert (code, err) == (0, "")
    pictures = [f"{name}.png" for name in study.links["plots"]]
    assert "learning.png" in pictures and "total_steps.png" in pictures
    tables = ["results.csv", "results.parquet", "comparisons.csv", "comparisons.parquet"]
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted([*tables, "study.json", *pictures])
    assert out.startswith(f"Fetching study {study.id} into {tmp_path}:\n")
    assert out.endswith(f"Wrote {5 + len(pictures)} files to {tmp_path}\n")
    assert (tmp_path / "results.csv").read_bytes() == api.study_csv(study.id)
    assert (tmp_path / "comparisons.csv").read_bytes() == api.study_comparisons_csv(study.id)
    compared = pq.read_table(tmp_path / "comparisons.parquet").to_pylist()
    assert len(compared) == len(study.metrics)  # one method against the baseline, per metric
    table = pq.read_table(tmp_path / "results.parquet").to_pylist()
    assert [row["job_id"] for row in table] == [row["job_id"] for row in api.study_table(study.id)]
    assert json.loads((tmp_path / "study.json").read_text())["points"] == study.raw["points"]
    image = imread(io.BytesIO((tmp_path / "learning.png").read_bytes()), format="png")
    assert image[..., :3].std() > 0.05


def test_fetch_of_a_job_without_results_or_an_unknown_one_exits_2(
    live_api: LiveApi, tmp_path: Path, capsys: pytest.CaptureFixture[str], api: Client
) -> None:
    failed = api.wait(api.submit(CROWDED).id, poll_s=0.05, timeout_s=WAIT_S)
    out_dir = tmp_path / "none"
    assert main(["fetch", str(failed.id), "--out", str(out_dir), "--url", live_api.url]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"nanonav fetch: job {failed.id} has no results: it failed (")
    assert not out_dir.exists()
    assert main(["fetch", "999999999", "--out", str(out_dir), "--url", live_api.url]) == 2
    assert capsys.readouterr().err == (
        "nanonav fetch: 404 Job not found: there is no job 999999999\n"
    )
    assert (
        main(["fetch", "--study", "999999999", "--out", str(out_dir), "--url", live_api.url]) == 2
    )
    assert "404 Study not found" in capsys.readouterr().err
    assert not out_dir.exists()


# ---------------------------------------------------------------- delete


def test_delete_removes_a_finished_job_or_study_and_explains_a_refusal(
    live_api: LiveApi, capsys: pytest.CaptureFixture[str], api: Client
) -> None:
    url = ["--url", live_api.url]
    job = api.wait(api.submit({**TINY, "seed": 31}).id, poll_s=0.05, timeout_s=WAIT_S)
    study = api.wait_study(api.submit_study(STUDY).id, poll_s=0.1, timeout_s=WAIT_S)
    one_of_study = next(api.jobs(study=study.id)).id
    assert main(["delete", str(one_of_study), *url]) == 2
    assert capsys.readouterr().err.startswith(
        f"nanonav delete: 409 Job belongs to a study: job {one_of_study} belongs to study "
        f"{study.id}: delete the study instead"
    )
    assert main(["delete", str(job.id), *url]) == 0
    assert capsys.readouterr().out == f"Deleted job {job.id}\n"
    assert main(["delete", "--study", str(study.id), *url]) == 0
    assert capsys.readouterr().out == f"Deleted study {study.id} and its jobs\n"
    assert main(["delete", str(job.id), *url]) == 2
    gone = capsys.readouterr().err
    assert gone == f"nanonav delete: 404 Job not found: there is no job {job.id}\n"
    assert main(["delete", *url]) == 2
    assert "give a job ID, or --study ID" in capsys.readouterr().err


# ---------------------------------------------------------------- jobs


def table_rows(out: str) -> list[list[str]]:
    lines = out.splitlines()
    assert lines[0].split() == [
        "id", "status", "progress", "policy", "robots", "seed", "study", "created"
    ]  # fmt: skip
    return [line.split() for line in lines[2:]]


def test_jobs_lists_newest_first_and_filters(
    live_api: LiveApi,
    finished: tuple[Job, Study],
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    job, study = finished
    assert main(["jobs", "--study", str(study.id), "--url", live_api.url]) == 0
    rows = table_rows(capsys.readouterr().out)
    assert len(rows) == 4
    assert [int(r[0]) for r in rows] == sorted((int(r[0]) for r in rows), reverse=True)
    assert {(r[1], r[2], r[6]) for r in rows} == {("succeeded", "100%", str(study.id))}
    assert sorted((r[3], r[5]) for r in rows) == sorted(
        (p, str(s)) for p in ("q_learning", "gradient") for s in (4, 5)
    )

    monkeypatch.setenv("NANONAV_URL", live_api.url)  # the default --url
    assert main(["jobs", "--limit", "2"]) == 0
    rows = table_rows(capsys.readouterr().out)
    assert len(rows) == 2 and int(rows[0][0]) > int(rows[1][0]) >= job.id

    assert main(["jobs", "--status", "succeeded", "--limit", "100"]) == 0
    rows = table_rows(capsys.readouterr().out)
    assert {r[1] for r in rows} == {"succeeded"}
    (row,) = [r for r in rows if r[0] == str(job.id)]
    assert row[3:7] == ["q_learning", "2", "21", "-"]

    assert main(["jobs", "--status", "finished"]) == 2
    assert "invalid choice: 'finished'" in capsys.readouterr().err


def test_an_unreachable_server_exits_1_naming_it(capsys: pytest.CaptureFixture[str]) -> None:
    url = f"http://127.0.0.1:{free_port()}"
    assert main(["jobs", "--url", url]) == 1
    out, err = capsys.readouterr()
    assert out == ""
    assert err.startswith(f"nanonav jobs: cannot reach the NanoNav API at {url}: ")
    assert err.count("\n") == 1


# ---------------------------------------------------------------- real processes


def nanonav(*args: str, env: dict[str, str] | None = None) -> subprocess.Popen[str]:
    return subprocess.Popen(
        [sys.executable, "-m", "nanonav.cli", *args],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=env or clean_environment(),
    )


def test_submit_and_jobs_run_as_processes(live_api: LiveApi, tmp_path: Path) -> None:
    env = clean_environment(NANONAV_URL=live_api.url)
    submit = nanonav("submit", write(tmp_path, TINY), "--seed", "31", "--wait", env=env)
    out, err = submit.communicate(timeout=WAIT_S)
    assert (submit.returncode, err) == (0, "")
    job_id = submitted_id(out)
    assert "Table 1: custom scenario, seed 31, 2 robots" in out

    listing = nanonav("jobs", "--limit", "1", env=env)
    out, err = listing.communicate(timeout=WAIT_S)
    assert (listing.returncode, err) == (0, "")
    assert table_rows(out)[0][:2] == [str(job_id), "succeeded"]

    url = f"http://127.0.0.1:{free_port()}"
    unreachable = nanonav("jobs", "--url", url, env=env)
    out, err = unreachable.communicate(timeout=WAIT_S)
    assert (unreachable.returncode, out) == (1, "")
    assert err.startswith(f"nanonav jobs: cannot reach the NanoNav API at {url}")


def test_ctrl_c_while_waiting_exits_130_and_leaves_the_job_running(
    live_api: LiveApi, tmp_path: Path, api: Client
) -> None:
    process = nanonav("submit", write(tmp_path, LONG), "--wait", "--url", live_api.url)
    job_id: int | None = None
    try:
        assert process.stdout is not None
        job_id = submitted_id(process.stdout.readline())
        while api.job(job_id).status == "queued":
            time.sleep(0.05)
        process.send_signal(signal.SIGINT)
        out, err = process.communicate(timeout=WAIT_S)
        assert (process.returncode, out) == (130, "")
        assert err == (
            f"nanonav submit: stopped waiting; job {job_id} goes on on the server "
            f"({live_api.url}/jobs/{job_id})\n"
        )
        job = api.job(job_id)
        assert job.status == "running" and not job.cancel_requested
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()
        # Whatever happened, the shared worker must not spend minutes on this long job.
        if job_id is not None:
            api.cancel(job_id)
    assert job_id is not None
    assert api.wait(job_id, poll_s=0.05, timeout_s=WAIT_S).status == "cancelled"


def test_the_client_and_the_command_load_neither_service_worker_nor_engine() -> None:
    probe = (
        "import sys, nanonav.client, nanonav.cli; "
        "print(sorted({m.split('.')[0] for m in sys.modules} & {'service', 'worker', 'numba'}))"
    )
    done = subprocess.run(
        [sys.executable, "-c", probe], capture_output=True, text=True, timeout=60, check=True
    )
    assert done.stdout == "[]\n"


def test_set_gives_a_field_by_its_dotted_name_or_is_refused_naming_it(
    capsys: pytest.CaptureFixture[str],
) -> None:
    from nanonav.cli.common import parse_setting, with_settings

    scenario: dict[str, Any] = {"learning": {"alpha": 0.1}}
    with_settings(scenario, [parse_setting(text) for text in (
        "learning.episodes=20", "robots.policy=gradient", "cells.capacity=null")])  # fmt: skip
    assert scenario == {"learning": {"alpha": 0.1, "episodes": 20},
                        "robots": {"policy": "gradient"}, "cells": {"capacity": None}}  # fmt: skip
    url = ["--url", "http://127.0.0.1:9"]
    assert main(["submit", "--preset", "paper-single", "--set", "episodes", *url]) == 2
    assert "not FIELD=VALUE: 'episodes'" in capsys.readouterr().err
    assert main(["submit", "--preset", "paper-single", "--set", "robots=3", "--set",
                 "robots.count=2", *url]) == 2  # fmt: skip
    assert capsys.readouterr().err == (
        "nanonav submit: --set robots.count: robots is not a section\n"
    )


def test_a_job_decided_by_a_policy_from_elsewhere_is_named_by_it() -> None:
    """A job evaluating a sent policy was headed "q_learning, 0 training episodes"."""
    from nanonav.cli.tables import _decided_by, policy_words

    sent = {"robots": {"policy": "q_learning"}, "policy_from": "policy-3"}
    learned = {"robots": {"policy": "q_learning"}, "policy_from": 12}
    own = {"robots": {"policy": "q_learning"}, "learning": {"actions": "directions"}}
    assert [policy_words(s) for s in (sent, learned, own)] == [
        "policy-3, sent", "job 12's table", "q_learning (directions)"
    ]  # fmt: skip
    assert [_decided_by(s) for s in (sent, learned, own)] == ["policy-3", "job-12", "q_learning"]
    # with the sent policy's record at hand, by its name and kind too
    record = SimpleNamespace(name="chemotaxis net", kind="network")
    assert policy_words(sent, cast(Policy, record)) == 'policy-3 "chemotaxis net", a network sent'
    assert policy_words(sent, cast(Policy, SimpleNamespace(name=None, kind="table"))) == (
        "policy-3, a table sent"
    )
