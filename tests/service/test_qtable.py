"""The learned Q-table through the API: the greedy action of every state in the answer, and
its picture, drawn on first request from the stored arrays."""

from __future__ import annotations

import csv
import io

import numpy as np
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


def test_a_job_without_a_qtable_answers_an_empty_greedy_table(
    api: Api, api_settings: Settings
) -> None:
    baseline = ran(api.store, api_settings, {**TINY, "robots": {"count": 1, "policy": "gradient"}})
    answer = api.client.get(f"/jobs/{baseline}/qtable").json()
    assert answer == {"states": [], "actions": [], "values": [], "visits": [], "greedy": []}


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


def test_a_job_without_a_qtable_downloads_empty_tables(api: Api, api_settings: Settings) -> None:
    baseline = ran(api.store, api_settings, {**TINY, "robots": {"count": 1, "policy": "gradient"}})
    text = api.client.get(f"/jobs/{baseline}/qtable?format=csv").text
    assert text == "state,action,value,visits\n"
    npz = api.client.get(f"/jobs/{baseline}/qtable?format=npz").content
    with np.load(io.BytesIO(npz), allow_pickle=False) as arrays:
        assert arrays["states"].size == 0 and arrays["values"].size == 0


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


def test_the_qtable_picture_of_a_baseline_job_is_404_saying_why(
    api: Api, api_settings: Settings
) -> None:
    baseline = ran(api.store, api_settings, {**TINY, "robots": {"count": 1, "policy": "random"}})
    body = assert_problem(api.client.get(f"/jobs/{baseline}/plots/qtable.png"), 404)
    assert body["type"].endswith("no-qtable")
    assert body["detail"] == (
        f"job {baseline} learned no Q-table: its robots used the 'random' policy, and only "
        "q_learning learns one"
    )
    assert api.store.plot(baseline, "qtable") is None
