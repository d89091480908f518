"""The learned Q-table through the API: the greedy action of every state in the answer, and
its picture, drawn on first request from the stored arrays."""

from __future__ import annotations

import csv
import io

import numpy as np
import pytest
from matplotlib.image import imread

from nanonav.engine import qlearning
from nanonav.policy import greedy_table
from nanonav.settings import Settings
from nanonav.store import JobStatus
from tests.conftest import Api
from tests.service.conftest import TINY, ran
from tests.service.test_api import assert_problem

# ---------------------------------------------------------------- the greedy table


def test_the_qtable_answer_names_the_greedy_action_of_every_state(api: Api, trained: int) -> None:
    answer = api.client.get(f"/jobs/{trained}/qtable").json()
    values = np.asarray(answer["values"])
    visits = np.asarray(answer["visits"])
    greedy = answer["greedy"]
    assert [g["state"] for g in greedy] == answer["states"]
    expected = greedy_table(answer["states"], answer["actions"], values, visits)
    assert greedy == [g.to_dict() for g in expected]
    seen = [g for g in greedy if g["learned"]]
    assert seen, "a trained table has visited states"
    for g in seen:
        row = values[answer["states"].index(g["state"])]
        assert g["value"] == row.max()
        assert row[answer["actions"].index(g["action"])] == row.max()
    unseen = [g for g in greedy if not g["learned"]]
    assert all(g["action"] == "unvisited" and g["visits"] == 0 for g in unseen)
    assert sum(g["visits"] for g in greedy) == visits.sum()


def test_per_robot_tables_give_the_greedy_table_of_their_mean(
    api: Api, api_settings: Settings
) -> None:
    own = {**TINY, "learning": {**TINY["learning"], "shared_table": False}}
    job_id = ran(api.store, api_settings, own)
    answer = api.client.get(f"/jobs/{job_id}/qtable").json()
    visits = np.asarray(answer["visits"])
    assert visits.shape == (2, 72, 4)
    assert [g["visits"] for g in answer["greedy"]] == visits.sum(axis=(0, 2)).tolist()


def job_without_a_table(api: Api, settings: Settings, kind: str) -> tuple[int, str]:
    """A succeeded job that has no Q-table, of ``kind``; and why, as its 404 says."""
    if kind == "network":
        from tests.service.test_network_policies import EVALUATE, network

        source = network(api)["policy_from"]
        job = ran(api.store, settings, {**EVALUATE, "policy_from": source})
        return job, f"it evaluated {source}, a network, which has none"
    if kind == "untrained":
        job = ran(api.store, settings, {**TINY, "learning": {"episodes": 0, "max_steps": 60}})
        return job, (
            "it trained for 0 episodes (learning.episodes) and evaluated no policy_from, so "
            "its table holds nothing learned"
        )
    job = ran(api.store, settings, {**TINY, "robots": {"count": 1, "policy": kind}})
    return job, f"its robots used the {kind!r} policy, and only q_learning learns one"


@pytest.mark.parametrize("kind", ["gradient", "random", "untrained", "network"])
def test_a_job_without_a_qtable_is_404_saying_why_and_offers_none(
    api: Api, api_settings: Settings, kind: str
) -> None:
    job, why = job_without_a_table(api, api_settings, kind)
    assert api.store.get(job).status is JobStatus.SUCCEEDED
    detail = f"job {job} learned no Q-table: {why}"
    for path in ("qtable", "qtable?format=csv", "qtable?format=npz", "plots/qtable.png"):
        body = assert_problem(api.client.get(f"/jobs/{job}/{path}"), 404)
        assert body["type"].endswith("no-qtable") and body["detail"] == detail, path
    links = api.client.get(f"/jobs/{job}").json()["links"]
    assert links["qtable"] is None and "qtable" not in links["plots"]
    assert links["metrics"] == f"/jobs/{job}/metrics"
    listed = api.client.get("/jobs").json()["jobs"]
    assert [j["links"]["qtable"] for j in listed if j["id"] == job] == [None]
    page = api.client.get(f"/ui/jobs/{job}").text
    assert f"/jobs/{job}/qtable" not in page and f"/jobs/{job}/plots/qtable.png" not in page
    assert f"/jobs/{job}/metrics" in page


def test_a_learning_job_offers_its_qtable_and_its_download(api: Api, trained: int) -> None:
    links = api.client.get(f"/jobs/{trained}").json()["links"]
    assert links["qtable"] == f"/jobs/{trained}/qtable"
    assert api.client.get(links["qtable"]).status_code == 200
    page = api.client.get(f"/ui/jobs/{trained}").text
    assert f'href="/jobs/{trained}/qtable"' in page


def test_a_queued_jobs_qtable_is_409_not_404(api: Api) -> None:
    job = api.client.post("/jobs", json={**TINY, "robots": {"count": 1, "policy": "random"}})
    body = assert_problem(api.client.get(f"/jobs/{job.json()['id']}/qtable"), 409)
    assert body["type"].endswith("results-unavailable")


def test_per_robot_tables_of_values_near_the_float_limit_answer_a_finite_greedy_table(
    api: Api, api_settings: Settings
) -> None:
    # a policy kept before values were bounded (MAX_Q): their sum over robots overflowed
    states, actions = qlearning.labels("behaviors")
    values = np.tile([1.7e308, -1.7e308, 1.6e308, 1.5e308], (2, len(states), 1))
    policy = api.store.policies.add(
        action_set="behaviors",
        communication=("none",),
        states=states,
        actions=actions,
        values=values,
    )
    learning = {"episodes": 0, "max_steps": 60, "shared_table": False}
    scenario = {"robots": {"count": 2}, "learning": learning, "policy_from": policy.policy_from}
    job_id = ran(api.store, api_settings, scenario)
    assert api.store.get(job_id).status is JobStatus.SUCCEEDED
    response = api.client.get(f"/jobs/{job_id}/qtable")
    assert response.status_code == 200, response.text
    answer = response.json()
    assert np.array_equal(np.asarray(answer["values"]), values)
    assert {(g["action"], g["value"]) for g in answer["greedy"]} == {("follow_gradient", 1.7e308)}
    for format in ("csv", "npz"):
        assert api.client.get(f"/jobs/{job_id}/qtable?format={format}").status_code == 200
    assert api.client.get(f"/jobs/{job_id}/plots/qtable.png").status_code == 200


# ---------------------------------------------------------------- downloads


def test_the_qtable_downloads_as_npz_and_csv_hold_what_the_json_holds(
    api: Api, trained: int
) -> None:
    answer = api.client.get(f"/jobs/{trained}/qtable").json()
    npz = api.client.get(f"/jobs/{trained}/qtable?format=npz")
    assert npz.status_code == 200 and npz.headers["content-type"] == "application/octet-stream"
    assert "qtable.npz" in npz.headers["content-disposition"]
    with np.load(io.BytesIO(npz.content), allow_pickle=False) as arrays:
        assert arrays["states"].tolist() == answer["states"]
        assert arrays["actions"].tolist() == answer["actions"]
        assert np.array_equal(arrays["values"], np.asarray(answer["values"]))
        assert np.array_equal(arrays["visits"], np.asarray(answer["visits"]))
    text = api.client.get(f"/jobs/{trained}/qtable?format=csv")
    assert text.headers["content-type"].startswith("text/csv")
    rows = list(csv.reader(io.StringIO(text.text)))
    assert rows[0] == ["state", "action", "value", "visits"]
    assert len(rows) - 1 == len(answer["states"]) * len(answer["actions"])
    for state, action, value, visits in rows[1:]:
        i, a = answer["states"].index(state), answer["actions"].index(action)
        assert float(value) == answer["values"][i][a] and int(visits) == answer["visits"][i][a]


def test_per_robot_tables_download_as_csv_with_a_robot_column(
    api: Api, api_settings: Settings
) -> None:
    own = {**TINY, "learning": {**TINY["learning"], "shared_table": False}}
    job_id = ran(api.store, api_settings, own)
    rows = list(csv.reader(io.StringIO(api.client.get(f"/jobs/{job_id}/qtable?format=csv").text)))
    assert rows[0] == ["robot", "state", "action", "value", "visits"]
    assert len(rows) - 1 == 2 * 72 * 4
    assert {row[0] for row in rows[1:]} == {"0", "1"}


def test_an_unknown_qtable_format_is_a_422_naming_it(api: Api, trained: int) -> None:
    body = assert_problem(api.client.get(f"/jobs/{trained}/qtable?format=xml"), 422)
    assert body["errors"][0]["loc"] == ["query", "format"]


# ---------------------------------------------------------------- the picture


def test_the_qtable_picture_is_drawn_from_the_stored_table_and_kept(api: Api, trained: int) -> None:
    job = api.client.get(f"/jobs/{trained}").json()
    assert job["links"]["plots"]["qtable"] == f"/jobs/{trained}/plots/qtable.png?v=2"
    response = api.client.get(job["links"]["plots"]["qtable"])
    assert response.status_code == 200, response.text
    assert response.headers["content-type"] == "image/png"
    image = imread(io.BytesIO(response.content), format="png")
    assert image.shape[:2] == (1500, 830)  # 72 states x 4 actions: a tall picture
    assert float(image[..., :3].std()) > 0.05
    assert api.store.plot(trained, "qtable.v2") == response.content
