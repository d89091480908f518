"""Any physics a client sends, through the API with a key: a job or a study whose scenario the
schema admits (subnormal, huge and boundary values of every physical field drawn often) is
queued or refused with a 422 naming a field of the body, never a 5xx. The API-level companion of
``tests/engine/test_scenario_bounds.py``, whose strategies it draws from; schemathesis
(``test_fuzz.py``) rarely reaches this corner, as it needs the active Brownian model and an
extreme value in one body."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import httpx
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from nanonav.settings import Settings
from tests.conftest import SCRIPTED
from tests.engine.test_scenario_bounds import EXTREMES, brownian_scenarios, lattice_scenarios
from tests.service.test_security import KEY_A, bearer, served

HEADERS = {**SCRIPTED, **bearer(KEY_A)}
EXAMPLES = settings(max_examples=150, deadline=None, suppress_health_check=list(HealthCheck))
PHYSICAL = ("viscosity_mpa_s", "robot_radius_um", "temperature_k", "dt_s", "time_limit_s",
            "molecule_diffusion_um2_s", "decay_rate_s", "secretion_molecules_s")  # fmt: skip


@pytest.fixture(scope="module")
def api(tmp_path_factory: pytest.TempPathFactory) -> Iterator[httpx.Client]:
    """A keyed API over a SQLite file of this module's, served by uvicorn."""
    url = f"sqlite:///{tmp_path_factory.mktemp('physics') / 'nanonav.db'}"
    with served(Settings(database_url=url, api_keys=KEY_A)) as server:
        server.client.headers.update(HEADERS)
        yield server.client


def assert_queued_or_named(response: httpx.Response) -> None:
    assert response.status_code in (202, 422), (response.status_code, response.text[:500])
    if response.status_code == 422:
        errors = response.json()["errors"]
        assert errors and all(error["loc"][0] == "body" for error in errors), errors


@EXAMPLES
@given(st.one_of(brownian_scenarios(), lattice_scenarios()))
def test_any_physics_sent_as_a_job_is_queued_or_refused_naming_a_field(
    api: httpx.Client, scenario: dict[str, Any]
) -> None:
    assert_queued_or_named(api.post("/jobs", json={**scenario, "learning": {"episodes": 0}}))


@EXAMPLES
@given(
    st.sampled_from(PHYSICAL),
    st.lists(st.one_of(st.sampled_from(EXTREMES), st.floats(allow_nan=False, allow_infinity=False)),
             min_size=1, max_size=3, unique=True),
    st.sampled_from(["tumour-microswimmers", "tumour-nanorobots", "tumour-passive"]),
)  # fmt: skip
def test_any_grid_of_physical_values_is_queued_or_refused_naming_a_field(
    api: httpx.Client, field: str, values: list[float], preset: str
) -> None:
    body = {
        "base": {"preset": preset, "learning": {"episodes": 0}},
        "grid": {f"physics.{field}": values},
        "seeds": [1],
    }
    response = api.post("/studies", json=body)
    assert response.status_code in (202, 422), (response.status_code, response.text[:500])
    if response.status_code == 422:
        errors = response.json()["errors"]
        assert all(error["loc"][:2] in (["body", "grid"], ["body", "base"]) for error in errors)


def test_the_issue_s_tiny_viscosity_is_422_at_its_field(api: httpx.Client) -> None:
    answer = api.post(
        "/jobs", json={"preset": "tumour-nanorobots", "physics": {"viscosity_mpa_s": 1e-310}}
    )
    assert answer.status_code == 422, answer.text
    assert answer.json()["errors"][0]["loc"] == ["body", "physics", "viscosity_mpa_s"]
