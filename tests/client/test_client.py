"""The client against a real API process and a real worker process: jobs, studies, and the
errors a script sees."""

from __future__ import annotations

import csv
import io
import statistics
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow.parquet as pq
import pytest
from matplotlib.image import imread

from nanonav.client import ApiError, Client, Job, ServerUnreachable, Study
from tests.conftest import LiveApi
from tests.processes import free_port

pytestmark = pytest.mark.timeout(180)

TINY: dict[str, Any] = {"robots": {"count": 2}, "learning": {"episodes": 2, "max_steps": 60}}
# Passes validation, then fails in the engine: no room for the obstacles.
CROWDED: dict[str, Any] = {
    "robots": {"count": 10000},
    "obstacles": {"count": 300, "radius": 3.0},
    "learning": {"episodes": 0, "max_steps": 5},
}
# Random walkers in a big cube: minutes of work, unless cancelled.
LONG: dict[str, Any] = {
    "space": {"size": 1000},
    "robots": {"count": 50, "policy": "random"},
    "learning": {"episodes": 900, "max_steps": 20_000},
}
STUDY: dict[str, Any] = {
    "name": "two policies",
    "base": {"robots": {"count": 1}, "learning": {"episodes": 3, "max_steps": 150}},
    "grid": {"robots.policy": ["q_learning", "gradient"]},
    "seeds": [4, 5],
    "compare": "robots.policy",
}
WAIT_S = 60.0


@pytest.fixture
def api(live_api: LiveApi) -> Iterator[Client]:
    with Client(live_api.url, timeout=10) as client:
        yield client


def decode_png(png: bytes) -> np.ndarray[Any, Any]:
    assert png.startswith(b"\x89PNG\r\n\x1a\n")
    image: np.ndarray[Any, Any] = imread(io.BytesIO(png), format="png")
    assert image.ndim == 3
    return image


def test_a_job_runs_and_its_metrics_arrays_qtable_and_pictures_come_back(api: Client) -> None:
    job = api.submit({**TINY, "seed": 5})
    assert (job.status, job.scenario["seed"], job.scenario["robots"]["count"]) == ("queued", 5, 2)
    assert job.links["self"] == f"/jobs/{job.id}" and job.study_id is None
    assert not job.finished

    seen: list[Job] = []
    done = api.wait(job.id, poll_s=0.05, timeout_s=WAIT_S, on_progress=seen.append)
    assert done.status == "succeeded" and done.finished
    assert done.progress == 1.0 and done.episode == done.episodes == 2 + 20
    assert done.error is None
    assert done.finished_at is not None and done.finished_at >= done.created_at
    assert seen[-1] is done and not any(j.finished for j in seen[:-1])
    assert api.job(job.id) == done  # ``raw`` is left out of the comparison

    metrics = api.metrics(job.id)
    assert metrics["completed"] is True
    assert metrics["scenario"] == done.scenario
    assert len(metrics["robots"]) == 2 and len(metrics["episodes"]) == 2

    arrays = api.arrays(job.id)
    rows = arrays["robots"].shape[0]
    assert arrays["robots"].shape == (rows, 2, 3) and arrays["robots"].dtype == np.float64
    assert arrays["step"].tolist() == list(range(rows))
    assert arrays["robot_steps"].tolist() == [r["total_steps"] for r in metrics["robots"]]
    strided = api.arrays(job.id, stride=10)
    assert strided["step"].tolist() == sorted({*range(0, rows, 10), rows - 1})
    np.testing.assert_array_equal(strided["robots"], arrays["robots"][strided["step"]])

    qtable = api.qtable(job.id)
    assert np.array(qtable["values"]).shape == (len(qtable["states"]), len(qtable["actions"]))
    assert "follow_gradient" in qtable["actions"]
    assert [g["state"] for g in qtable["greedy"]] == qtable["states"]
    assert decode_png(api.picture(job.id, "qtable")).shape[:2] == (1500, 830)

    heatmap = decode_png(api.picture(job.id, "heatmap_xy"))
    learning = decode_png(api.picture(job.id, "learning"))
    assert heatmap[..., :3].std() > 0.05 and learning[..., :3].std() > 0.05
    assert heatmap.shape != learning.shape or not np.array_equal(heatmap, learning)
    with pytest.raises(ValueError, match="heatmap_xz"):
        api.picture(job.id, "heatmap_ab")
    sliced = api.picture(job.id, "heatmap_xy", at=-20.0, resolution=20)
    assert decode_png(sliced).shape == heatmap.shape
    assert sliced != api.picture(job.id, "heatmap_xy")
    with pytest.raises(ValueError, match="only heatmaps"):
        api.picture(job.id, "learning", resolution=20)


def test_the_same_idempotency_key_gives_the_same_job(api: Client) -> None:
    first = api.submit(TINY, idempotency_key="client-test-retry")
    again = api.submit(TINY, idempotency_key="client-test-retry")
    assert again.id == first.id
    assert api.submit(TINY).id > first.id


def test_a_callback_url_reaches_the_server_which_refuses_it_without_webhook_hosts(
    api: Client,
) -> None:
    for submit in (
        lambda: api.submit(TINY, callback_url="https://hooks.example.org/x"),
        lambda: api.submit_study(
            {"base": TINY, "grid": {"robots.count": [1]}, "seeds": [1]},
            callback_url="https://hooks.example.org/x",
        ),
    ):
        with pytest.raises(ApiError) as refused:
            submit()
        assert refused.value.status == 422 and "sends no webhooks" in str(refused.value)


def test_listing_jobs_is_newest_first_and_stops_at_the_limit(api: Client) -> None:
    ids = [api.submit({**TINY, "seed": s}).id for s in range(3)]
    assert [j.id for j in api.jobs(limit=2)] == [ids[2], ids[1]]
    for job_id in ids:
        api.wait(job_id, poll_s=0.05, timeout_s=WAIT_S)
    succeeded = list(api.jobs(status="succeeded"))
    assert {j.status for j in succeeded} == {"succeeded"}
    assert set(ids) <= {j.id for j in succeeded}
    assert [j.id for j in succeeded] == sorted((j.id for j in succeeded), reverse=True)


def test_a_study_of_two_policies_by_two_seeds(api: Client, tmp_path: Path) -> None:
    created = api.submit_study(STUDY, idempotency_key="client-test-study")
    assert created.jobs.total == 4 and len(created.points) == 2
    assert created.spec["seeds"] == [4, 5]

    seen: list[Study] = []
    study = api.wait_study(created.id, poll_s=0.1, timeout_s=WAIT_S, on_progress=seen.append)
    assert study.status == "succeeded" and study.finished
    assert study.jobs.succeeded == study.jobs.finished == 4 and study.progress == 1.0
    assert study.finished_at is not None
    assert seen[-1] is study
    assert next(api.studies(limit=1)).id == study.id

    jobs = list(api.jobs(study=study.id))
    assert len(jobs) == 4 and {j.study_id for j in jobs} == {study.id}
    summaries = {
        (j.scenario["robots"]["policy"], j.scenario["seed"]): api.metrics(j.id)["summary"]
        for j in jobs
    }
    assert set(summaries) == {(p, s) for p in ("q_learning", "gradient") for s in (4, 5)}

    for point in study.points:
        policy = point.values["robots.policy"]
        steps = [summaries[(policy, seed)]["total_steps"] for seed in (4, 5)]
        found = point.metrics["total_steps"]
        assert found.n == 2
        assert found.mean == pytest.approx(statistics.fmean(steps))
        assert found.ci_low is not None and found.ci_high is not None
        assert found.mean is not None
        assert found.ci_low <= found.mean <= found.ci_high
    (comparison,) = study.comparisons
    assert (comparison.method, comparison.baseline) == ("gradient", "q_learning")
    differences = [
        summaries[("gradient", s)]["total_steps"] - summaries[("q_learning", s)]["total_steps"]
        for s in (4, 5)
    ]
    assert comparison.metrics["total_steps"].n == 2
    assert comparison.metrics["total_steps"].mean_difference == pytest.approx(
        statistics.fmean(differences)
    )

    table = api.study_table(study.id)
    assert sorted(row["job_id"] for row in table) == sorted(j.id for j in jobs)
    for row in table:
        assert isinstance(row["seed"], int) and isinstance(row["total_steps"], float)
        assert row["status"] == "succeeded"
        summary = summaries[(row["robots.policy"], row["seed"])]
        assert row["total_steps"] == summary["total_steps"]
        assert row["path_efficiency"] == summary["path_efficiency"]

    path = api.write_study_csv(study.id, tmp_path / "results.csv")
    written = list(csv.DictReader(io.StringIO(path.read_text(encoding="utf-8"))))
    assert [int(row["job_id"]) for row in written] == [row["job_id"] for row in table]
    assert [float(row["final_distance"]) for row in written] == [
        row["final_distance"] for row in table
    ]

    parquet = pq.read_table(io.BytesIO(api.study_parquet(study.id))).to_pylist()
    assert [row["job_id"] for row in parquet] == [row["job_id"] for row in table]
    assert [row["total_steps"] for row in parquet] == [row["total_steps"] for row in table]

    # the paired comparisons, a row per metric of gradient against q_learning
    compared = api.study_comparisons(study.id)
    assert [row["metric"] for row in compared] == list(study.metrics)
    for row in compared:
        difference = study.comparisons[0].metrics[str(row["metric"])]
        assert (row["robots.policy"], row["baseline"]) == ("gradient", "q_learning")
        assert row["n"] == difference.n == 2
        assert row["p_value"] == difference.p_value and row["p_holm"] == difference.p_holm
        assert row["resolvable"] == difference.resolvable
    in_parquet = pq.read_table(io.BytesIO(api.study_comparisons_parquet(study.id))).to_pylist()
    assert [(r["metric"], r["mean_difference"]) for r in in_parquet] == [
        (r["metric"], r["mean_difference"]) for r in compared
    ]

    image = decode_png(api.study_picture(study.id, "total_steps"))
    assert image[..., :3].std() > 0.05


def test_an_invalid_scenario_raises_one_error_naming_each_field(api: Client) -> None:
    with pytest.raises(ApiError) as caught:
        api.submit({"robots": {"count": 0}, "learning": {"alpha": 0}})
    error = caught.value
    assert (error.status, error.title, error.instance) == (422, "Invalid input", "/jobs")
    assert error.type == "urn:nanonav:problem:invalid-input"
    assert [e["pointer"] for e in error.errors] == ["#/robots/count", "#/learning/alpha"]
    assert str(error).splitlines() == [
        "422 Invalid input: #/robots/count: Input should be greater than or equal to 1",
        "  #/robots/count: Input should be greater than or equal to 1",
        "  #/learning/alpha: Input should be greater than 0",
    ]


def test_an_invalid_study_grid_names_the_value_at_fault(api: Client) -> None:
    with pytest.raises(ApiError) as caught:
        api.submit_study({"grid": {"robots.count": [1, 0]}, "seeds": [1]})
    assert caught.value.status == 422
    assert [e["pointer"] for e in caught.value.errors] == ["#/grid/robots.count/1"]
    assert "greater than or equal to 1" in caught.value.errors[0]["detail"]
    # the only field's message is the detail: said once
    assert str(caught.value).startswith("422 Invalid input: #/grid/robots.count/1: at the grid")
    assert "\n" not in str(caught.value)

    with pytest.raises(ApiError) as caught:
        api.submit_study({"grid": {"robots.polcy": ["gradient"]}, "replicates": 2})
    assert [e["pointer"] for e in caught.value.errors] == ["#/grid/robots.polcy"]


def test_unknown_ids_are_404s(api: Client) -> None:
    with pytest.raises(ApiError) as caught:
        api.job(10**12)
    assert caught.value.status == 404
    assert caught.value.type == "urn:nanonav:problem:job-not-found"
    assert str(caught.value) == f"404 Job not found: there is no job {10**12}"
    with pytest.raises(ApiError) as caught:
        api.study(10**12)
    assert (caught.value.status, caught.value.title) == (404, "Study not found")
    with pytest.raises(ApiError) as caught:
        api.study_table(10**12)
    assert caught.value.status == 404


def test_a_failed_job_carries_its_error_and_has_no_results(api: Client) -> None:
    job = api.wait(api.submit(CROWDED).id, poll_s=0.05, timeout_s=WAIT_S)
    assert job.status == "failed" and job.finished
    assert job.error is not None and "could not place obstacle" in job.error
    with pytest.raises(ApiError) as caught:
        api.metrics(job.id)
    assert (caught.value.status, caught.value.type) == (
        409,
        "urn:nanonav:problem:results-unavailable",
    )
    with pytest.raises(ApiError) as caught:
        api.cancel(job.id)
    assert caught.value.status == 409 and "already finished" in str(caught.value)


def test_wait_times_out_and_cancel_stops_a_long_job(api: Client) -> None:
    job = api.submit(LONG)
    with pytest.raises(TimeoutError, match=f"job {job.id} is still (queued|running) after 0.3 s"):
        api.wait(job.id, poll_s=0.05, timeout_s=0.3)
    assert api.cancel(job.id).cancel_requested is True
    ended = api.wait(job.id, poll_s=0.05, timeout_s=WAIT_S)
    assert ended.status == "cancelled"


def test_a_finished_job_is_deleted_and_an_unfinished_one_refused(api: Client) -> None:
    done = api.wait(api.submit(TINY).id, poll_s=0.05, timeout_s=WAIT_S)
    api.delete(done.id)
    for call in (lambda: api.job(done.id), lambda: api.delete(done.id)):
        with pytest.raises(ApiError) as caught:
            call()
        assert (caught.value.status, caught.value.title) == (404, "Job not found")
    long = api.submit(LONG)
    with pytest.raises(ApiError) as caught:
        api.delete(long.id)
    assert caught.value.status == 409 and "cancel it first" in str(caught.value)
    api.cancel(long.id)
    api.wait(long.id, poll_s=0.05, timeout_s=WAIT_S)
    api.delete(long.id)


def test_an_ended_study_is_deleted_with_its_jobs(api: Client) -> None:
    spec = {"name": "long", "base": LONG, "grid": {"robots.policy": ["random", "gradient"]},
            "seeds": [0]}  # fmt: skip
    study = api.submit_study(spec)
    with pytest.raises(ApiError) as caught:
        api.delete_study(study.id)
    assert caught.value.status == 409 and caught.value.title == "Study not finished"
    api.cancel_study(study.id)
    api.wait_study(study.id, poll_s=0.05, timeout_s=WAIT_S)
    jobs = [job.id for job in api.jobs(study=study.id)]
    api.delete_study(study.id)
    with pytest.raises(ApiError) as caught:
        api.study(study.id)
    assert caught.value.status == 404
    with pytest.raises(ApiError) as caught:
        list(api.jobs(study=study.id))
    assert caught.value.status == 404 and caught.value.title == "Study not found"
    with pytest.raises(ApiError) as caught:
        api.job(jobs[0])
    assert caught.value.status == 404


def test_an_unreachable_server_is_named(live_api: LiveApi) -> None:
    url = f"http://127.0.0.1:{free_port()}"
    with Client(url, timeout=2) as api, pytest.raises(ServerUnreachable) as caught:
        api.job(1)
    assert isinstance(caught.value, ApiError) and caught.value.status == 0
    assert str(caught.value).startswith(f"cannot reach the NanoNav API at {url}: ")


def test_the_url_comes_from_the_environment(
    live_api: LiveApi, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("NANONAV_URL", live_api.url + "/")
    with Client() as api:
        assert api.url == live_api.url
        assert api.submit(TINY).scenario["robots"]["count"] == 2
    monkeypatch.delenv("NANONAV_URL")
    with Client() as api:
        assert api.url == "http://127.0.0.1:8000"
