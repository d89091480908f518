"""Trajectory answers are bounded: large JSON is refused with the stride that fits, the .npz
is the stored file, and CSV streams."""

from __future__ import annotations

import csv
import io
import threading
from typing import Any

import ase.io
import httpx
import numpy as np
import pytest

from nanonav.scenario import Scenario
from nanonav.settings import Settings
from nanonav.store import JobStatus, JobStore
from nanonav.store.arrays import unpack
from nanonav.store.migrate import upgrade
from service.app import create_app
from tests.conftest import serve
from worker.job import run_job

SCENARIO = {"robots": {"count": 4}, "learning": {"episodes": 0, "max_steps": 60}}


def test_trajectory_answers_are_bounded_and_say_how_to_get_the_rest(sqlite_url: str) -> None:
    settings = Settings(database_url=sqlite_url, trajectory_json_values=1000)
    upgrade(sqlite_url)
    store = JobStore.from_url(sqlite_url)
    job = store.enqueue(SCENARIO, robot_steps=1, episodes=1)
    claim = store.claim("test", lease_s=30)
    assert claim is not None
    record = run_job(store, claim, settings, threading.Event())
    assert record is not None and record.status is JobStatus.SUCCEEDED
    stored = store.trajectory(job.id)
    rows = stored["step"].shape[0]
    with serve(create_app(settings)) as url, httpx.Client(base_url=url, timeout=30) as client:
        refused = client.get(f"/jobs/{job.id}/trajectory")
        assert refused.status_code == 422
        problem = refused.json()
        assert problem["errors"][0]["parameter"] == "stride"
        assert "?stride=2 or more" in problem["detail"] and "format=npz" in problem["detail"]

        fits = client.get(f"/jobs/{job.id}/trajectory", params={"stride": 2})
        assert fits.status_code == 200, fits.text
        body = fits.json()
        assert body["step"][:3] == [0, 2, 4] and body["step"][-1] == int(stored["step"][-1])
        assert len(body["obstacles"]) == 1  # they stand still: recorded once
        assert len(body["robots"]) == len(body["step"])

        npz = client.get(f"/jobs/{job.id}/trajectory", params={"format": "npz"})
        assert npz.content == store.trajectory_npz(job.id)
        assert np.array_equal(unpack(npz.content)["robots"], stored["robots"])

        text = client.get(f"/jobs/{job.id}/trajectory", params={"format": "csv"}).text
        reader = csv.DictReader(io.StringIO(text))
        # cells that take no payload: no load column (every run records the loads, all 0)
        assert "cell_loads" in stored and "load" not in (reader.fieldnames or [])
        table = list(reader)
        robots = [r for r in table if r["kind"] == "robot"]
        assert len(robots) == 4 * rows
        assert float(robots[-1]["x"]) == stored["robots"][-1, 3, 0]
        obstacles = [r for r in table if r["kind"] == "obstacle"]
        assert len(obstacles) == 10 and {r["step"] for r in obstacles} == {"0"}
    store.close()


def test_an_active_brownian_trajectory_carries_headings_and_sensed_readings(
    sqlite_url: str,
) -> None:
    # through the API, as a client would check the physics: JSON, CSV and npz alike
    scenario = {
        "physics": {"model": "active_brownian"},
        "robots": {"count": 3, "policy": "run_and_tumble"},
        "learning": {"episodes": 0, "max_steps": 40},
        "evaluation": {"worlds": 1},
    }
    settings = Settings(database_url=sqlite_url)
    upgrade(sqlite_url)
    store = JobStore.from_url(sqlite_url)
    with serve(create_app(settings)) as url, httpx.Client(base_url=url, timeout=30) as client:
        answer = client.post("/jobs", json=scenario)
        assert answer.status_code == 202, answer.text
        job_id = answer.json()["id"]
        resolved = client.get(f"/jobs/{job_id}").json()["scenario"]["physics"]
        assert resolved["diffusion_um2_s"] > 0 and resolved["rotational_diffusion_s"] > 0
        claim = store.claim("test", lease_s=30)
        assert claim is not None
        record = run_job(store, claim, settings, threading.Event())
        assert record is not None and record.status is JobStatus.SUCCEEDED
        metrics = client.get(f"/jobs/{job_id}/metrics").json()
        assert metrics["physics"]["persistence_length_um"] > 0
        body = client.get(f"/jobs/{job_id}/trajectory").json()
        headings = np.array(body["headings"])
        assert headings.shape == (len(body["step"]), 3, 3)
        assert np.allclose(np.linalg.norm(headings, axis=2), 1.0)
        assert np.array(body["sensed"]).shape == (len(body["step"]), 3)
        arrays = unpack(client.get(f"/jobs/{job_id}/trajectory", params={"format": "npz"}).content)
        assert np.array_equal(arrays["headings"], headings)
        text = client.get(f"/jobs/{job_id}/trajectory", params={"format": "csv"}).text
        table = list(csv.DictReader(io.StringIO(text)))
        robot = next(r for r in table if r["kind"] == "robot")
        assert float(robot["heading_x"]) == headings[0, 0, 0]
        assert robot["sensed"] != ""
        lattice = client.post("/jobs", json={"robots": {"policy": "uncontrolled"}})
        assert lattice.status_code == 422
        assert lattice.json()["errors"][0]["pointer"] == "#/robots/policy"
    store.close()


def test_a_swarm_trajectory_carries_cell_loads_deliveries_and_signals(sqlite_url: str) -> None:
    # cells that take payloads and robots that signal: JSON, CSV and npz agree
    scenario = {
        "preset": "paper-swarm",
        "cells": {"count": 2, "capacity": 3},
        "robots": {"count": 30, "policy": "rule", "exclusion": True},
        "communication": {"model": "attractant_repellent"},
        "learning": {"episodes": 0, "max_steps": 200},
        "evaluation": {"worlds": 1},
    }
    settings = Settings(database_url=sqlite_url)
    upgrade(sqlite_url)
    store = JobStore.from_url(sqlite_url)
    with serve(create_app(settings)) as url, httpx.Client(base_url=url, timeout=30) as client:
        answer = client.post("/jobs", json=scenario)
        assert answer.status_code == 202, answer.text
        job_id = answer.json()["id"]
        claim = store.claim("test", lease_s=30)
        assert claim is not None
        record = run_job(store, claim, settings, threading.Event())
        assert record is not None and record.status is JobStatus.SUCCEEDED
        summary = client.get(f"/jobs/{job_id}/metrics").json()["summary"]
        assert summary["cells_treated"] >= 1
        body = client.get(f"/jobs/{job_id}/trajectory").json()
        loads = np.array(body["cell_loads"])
        delivered = np.array(body["delivered_to"])
        assert loads.shape == (len(body["step"]), 2) and loads.max() <= 3
        assert np.array_equal(np.bincount(delivered[delivered >= 0], minlength=2), loads[-1])
        signals = np.array(body["signals"])
        assert signals.shape == (len(body["step"]), 30) and signals.max() > 0
        arrays = unpack(client.get(f"/jobs/{job_id}/trajectory", params={"format": "npz"}).content)
        assert np.array_equal(arrays["cell_loads"], loads)
        assert np.array_equal(arrays["signals"], signals)
        text = client.get(f"/jobs/{job_id}/trajectory", params={"format": "csv"}).text
        table = list(csv.DictReader(io.StringIO(text)))
        last = str(body["step"][-1])
        cells = [r for r in table if r["kind"] == "cell" and r["step"] == last]
        assert [int(r["load"]) for r in cells] == loads[-1].tolist()
        robots = [r for r in table if r["kind"] == "robot" and r["step"] == last]
        assert [float(r["signal"]) for r in robots] == signals[-1].tolist()
        # and a paper scenario's answer has no signals
        plain = client.post("/jobs", json={**SCENARIO, "evaluation": {"worlds": 1}})
        plain_id = plain.json()["id"]
        claim = store.claim("test", lease_s=30)
        assert claim is not None
        run_job(store, claim, settings, threading.Event())
        assert client.get(f"/jobs/{plain_id}/trajectory").json()["signals"] is None
    store.close()


def test_the_trajectory_as_extended_xyz_opens_in_ase_with_time_and_lengths_in_units(
    sqlite_url: str,
) -> None:
    """A frame per recorded step (at the stride asked), the robots, cells and obstacles as
    particles where the .npz has them, the box the cube, the time in seconds in the active
    Brownian physics and in steps in the lattice: read back by ASE, the format's own reader."""
    settings = Settings(database_url=sqlite_url)
    upgrade(sqlite_url)
    store = JobStore.from_url(sqlite_url)
    brownian: dict[str, Any] = {
        "physics": {"model": "active_brownian"},
        "robots": {"count": 3},
        "learning": {"episodes": 0, "max_steps": 40},
        "evaluation": {"worlds": 1},
    }
    lattice = {"robots": {"count": 2}, "learning": {"episodes": 0, "max_steps": 30},
               "evaluation": {"worlds": 1}}  # fmt: skip
    with serve(create_app(settings)) as url, httpx.Client(base_url=url, timeout=30) as client:
        for scenario, unit in ((brownian, "s"), (lattice, "step")):
            job_id = client.post("/jobs", json=scenario).json()["id"]
            claim = store.claim("test", lease_s=30)
            assert claim is not None
            record = run_job(store, claim, settings, threading.Event())
            assert record is not None and record.status is JobStatus.SUCCEEDED
            resolved = Scenario.model_validate(client.get(f"/jobs/{job_id}").json()["scenario"])
            arrays = store.trajectory(job_id)
            answer = client.get(f"/jobs/{job_id}/trajectory", params={"format": "xyz",
                                                                       "stride": 3})  # fmt: skip
            assert answer.status_code == 200, answer.text
            assert answer.headers["content-disposition"].endswith('-trajectory.xyz"')
            frames = ase.io.read(io.StringIO(answer.text), index=":", format="extxyz")
            rows = list(range(0, len(arrays["step"]), 3))
            if rows[-1] != len(arrays["step"]) - 1:
                rows.append(len(arrays["step"]) - 1)
            assert len(frames) == len(rows)
            step_s = resolved.physics.step_s if unit == "s" else 1.0
            for frame, row in zip(frames, rows, strict=True):
                kinds = list(frame.arrays["kind"])
                robots, cells = kinds.count("robot"), kinds.count("cell")
                assert (robots, cells) == (scenario["robots"]["count"], 1)
                assert kinds.count("obstacle") == resolved.obstacles.count
                assert list(frame.get_chemical_symbols()[:robots]) == ["N"] * robots
                assert np.allclose(frame.positions[:robots], arrays["robots"][row])
                assert np.allclose(frame.positions[robots : robots + 1], arrays["cells"][row])
                assert frame.info["step"] == int(arrays["step"][row])
                assert frame.info["time"] == pytest.approx(frame.info["step"] * step_s)
                assert frame.info["time_unit"] == unit
                assert not frame.pbc.any()
                assert np.allclose(frame.cell.lengths(), [resolved.space.size] * 3)
    store.close()
