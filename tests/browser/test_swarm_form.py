"""The new-job form's swarm fields in a real browser: each reaches the scenario's JSON only once
set, the JSON sets them back, and a job submitted with them runs with them."""

from __future__ import annotations

import json
import re

import httpx
import pytest
from playwright.sync_api import Page, expect

from tests.browser.conftest import Site, screenshot

pytestmark = pytest.mark.timeout(120)


def editor_json(page: Page) -> dict[str, object]:
    value: dict[str, object] = json.loads(page.locator("#scenario-json").input_value())
    return value


def test_the_swarms_fields_are_sent_only_once_set_and_the_job_runs_with_them(
    page: Page, site: Site
) -> None:
    page.goto(site.url + "/")
    exclusion = page.locator("input[name='robots.exclusion']")
    assert exclusion.evaluate("box => box.indeterminate")  # unset: the preset's
    page.select_option("select[name=preset]", "diffuse-tumour")
    page.fill("input[name='robots.count']", "6")
    assert editor_json(page) == {"preset": "diffuse-tumour", "robots": {"count": 6}}
    exclusion.click()
    page.fill("input[name='cells.capacity']", "2")
    page.select_option("select[name='communication.model']", "attractant")
    assert editor_json(page) == {
        "preset": "diffuse-tumour",
        "robots": {"count": 6, "exclusion": True},
        "cells": {"capacity": 2},
        "communication": {"model": "attractant"},
    }
    screenshot(page, "swarm-form")
    page.fill("input[name='cells.capacity']", "")
    assert "cells" not in editor_json(page)
    exclusion.click()
    assert editor_json(page)["robots"] == {"count": 6, "exclusion": False}

    page.click("#json-details summary")
    small = {"preset": "diffuse-tumour", "seed": 4, "robots": {"count": 6, "exclusion": True},
             "cells": {"count": 3, "capacity": 1}, "communication": {"model": "broadcast"},
             "learning": {"max_steps": 30}, "evaluation": {"worlds": 1}}  # fmt: skip
    page.fill("#scenario-json", json.dumps(small))
    assert exclusion.is_checked() and not exclusion.evaluate("box => box.indeterminate")
    expect(page.locator("input[name='cells.capacity']")).to_have_value("1")
    expect(page.locator("select[name='communication.model']")).to_have_value("broadcast")
    page.click("#job-form button[type=submit]")
    page.wait_for_url(re.compile(r"/ui/jobs/\d+$"))
    job_id = int(page.url.rsplit("/", 1)[1])
    scenario = httpx.get(f"{site.url}/jobs/{job_id}").json()["scenario"]
    assert scenario["robots"]["exclusion"] is True and scenario["cells"]["capacity"] == 1
    assert scenario["communication"]["model"] == "broadcast" and scenario["seed"] == 4

    page.goto(site.url + "/")
    page.click("#json-details summary")
    page.fill("#scenario-json", '{"robots": {"count": 3}}')
    assert exclusion.evaluate("box => box.indeterminate")
    expect(page.locator("input[name='cells.capacity']")).to_have_value("")
