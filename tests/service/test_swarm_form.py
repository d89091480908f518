"""The new-job form offers the swarm's settings, each sent only once set, and its preset."""

from __future__ import annotations

import re

from nanonav.scenario import PRESETS
from tests.conftest import Api


def test_the_form_has_the_swarms_fields_and_preset(api: Api) -> None:
    html = api.client.get("/").text
    assert "diffuse-tumour" in PRESETS
    assert '<option value="diffuse-tumour">diffuse-tumour</option>' in html
    for name, pointer in (
        ("robots.exclusion", "#/robots/exclusion"),
        ("cells.capacity", "#/cells/capacity"),
        ("communication.model", "#/communication/model"),
    ):
        assert re.search(rf'name="{re.escape(name)}"[^>]*data-pointer="{pointer}"', html), name
    assert re.search(r'name="robots.exclusion" type="checkbox"', html)
    assert re.search(r'name="cells.capacity" type="number" min="1"', html)
    menu = html[html.index('name="communication.model"') :].split("</select>")[0]
    options = re.findall(r'<option value="([^"]*)">', menu)
    assert options == ["", "none", "attractant", "attractant_repellent", "broadcast"]
    assert "checked" not in html[html.index('name="robots.exclusion"') :].split(">")[0]


def test_a_scenario_without_the_swarms_fields_runs_as_the_papers(api: Api) -> None:
    job = api.client.post("/jobs", json={"preset": "paper-swarm"}).json()
    scenario = job["scenario"]
    assert scenario["robots"]["exclusion"] is False and scenario["cells"]["capacity"] is None
    assert scenario["communication"]["model"] == "none"
