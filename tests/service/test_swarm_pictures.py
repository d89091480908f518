"""A swarm's job that delivers payloads has the treatment picture, linked from its links and
its page; a job of the paper's, or one whose robots only take up space, neither lists it nor
draws it."""

from __future__ import annotations

import io

from matplotlib.image import imread

from nanonav.scenario import preset_scenario
from nanonav.settings import Settings
from nanonav.store import JobStatus
from tests.conftest import Api
from tests.service.conftest import TINY, ran
from tests.service.test_api import assert_problem

# diffuse-tumour, small: three cells that one payload treats, a short episode
SWARM = preset_scenario(
    "diffuse-tumour",
    seed=0,
    robots={"count": 30},
    cells={"count": 3, "capacity": 1},
    communication={"model": "attractant"},
    learning={"max_steps": 80},
    evaluation={"worlds": 1},
).model_dump(mode="json")


def test_a_swarms_job_lists_and_draws_its_treatment(api: Api, api_settings: Settings) -> None:
    job_id = ran(api.store, api_settings, SWARM)
    assert api.store.get(job_id).status is JobStatus.SUCCEEDED
    assert "cells_treated" in api.store.metrics(job_id)["summary"]
    links = api.client.get(f"/jobs/{job_id}").json()["links"]["plots"]
    assert set(links) == {"trajectory", "concentration", "learning", "treatment"}  # rule: no Q
    assert links["treatment"] == f"/jobs/{job_id}/plots/treatment.png?v=3"
    assert links["trajectory"] == f"/jobs/{job_id}/plots/trajectory.png?v=4"
    served = api.client.get(links["treatment"])
    assert served.status_code == 200 and served.headers["content-type"] == "image/png"
    assert imread(io.BytesIO(served.content), format="png").shape[:2] == (700, 900)
    assert api.store.plot(job_id, "treatment.v3") == served.content  # kept once drawn
    page = api.client.get(f"/ui/jobs/{job_id}").text
    assert f'<img src="{links["treatment"]}"' in page
    assert "robots that take up space" in page and "signalling by attractant" in page


def test_a_job_without_the_swarms_numbers_has_no_treatment(
    api: Api, api_settings: Settings
) -> None:
    job_id = ran(api.store, api_settings, TINY)
    assert "cells_treated" not in api.store.metrics(job_id)["summary"]
    links = api.client.get(f"/jobs/{job_id}").json()["links"]["plots"]
    assert "treatment" not in links and "trajectory" in links
    body = assert_problem(api.client.get(f"/jobs/{job_id}/plots/treatment.png"), 404)
    assert body["type"].endswith("no-treatment")
    assert body["detail"].startswith(f"job {job_id} has no treatment to draw")
    assert api.store.plot(job_id, "treatment") is None
    assert "plots/treatment.png" not in api.client.get(f"/ui/jobs/{job_id}").text


def test_robots_that_only_take_up_space_offer_no_treatment(
    api: Api, api_settings: Settings
) -> None:
    microswimmers = preset_scenario(
        "tumour-microswimmers",
        seed=1,
        robots={"count": 3},
        physics={"time_limit_s": 0.6},
        learning={"episodes": 1},
        evaluation={"worlds": 1},
    ).model_dump(mode="json")
    job_id = ran(api.store, api_settings, microswimmers)
    assert "bumps" in api.store.metrics(job_id)["summary"]  # the swarm's numbers, no payload
    links = api.client.get(f"/jobs/{job_id}").json()["links"]["plots"]
    assert "treatment" not in links and "trajectory" in links
    body = assert_problem(api.client.get(f"/jobs/{job_id}/plots/treatment.png"), 404)
    assert body["type"].endswith("no-treatment")
    assert "deliver no payload" in body["detail"] and "cells.capacity" in body["detail"]
    assert "plots/treatment.png" not in api.client.get(f"/ui/jobs/{job_id}").text
