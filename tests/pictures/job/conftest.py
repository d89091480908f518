"""Two finished runs, a swarm and a single robot, drawn by many tests."""

import pytest

from nanonav.engine import SimulationResult, simulate
from tests.pictures.job.results import scenario


@pytest.fixture(scope="package")
def swarm() -> SimulationResult:
    return simulate(
        scenario(
            preset="paper-swarm",
            seed=5,
            learning={"episodes": 2, "max_steps": 200},
            biomarker={"model": "inverse_square"},
        )
    )


@pytest.fixture(scope="package")
def single() -> SimulationResult:
    return simulate(
        scenario(preset="paper-single", seed=2, learning={"episodes": 2, "max_steps": 200})
    )
