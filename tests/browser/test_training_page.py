"""A network trained in a job, watched from its page in a real browser: the training curve is
drawn while the job trains, grows as the worker writes rows, and stays once the job ends."""

from __future__ import annotations

from collections.abc import Iterator

import httpx
import pytest
from playwright.sync_api import Page, expect

from tests.browser.conftest import Site, screenshot
from tests.processes import FIRST_JOB_S, Worker

pytestmark = pytest.mark.timeout(300)

ROLLOUT = 1024 * 64  # decisions of one rollout of the trainer's default worlds
JSON = {"Content-Type": "application/json"}


@pytest.fixture
def trainer(site: Site) -> Iterator[Worker]:
    """A worker that trains, beside the site's worker that does not."""
    worker = Worker(site.database_url, site.directory / "trainer.log", "--train",
                    NANONAV_PROGRESS_INTERVAL_S="0.2")  # fmt: skip
    try:
        worker.wait_ready()
        yield worker
    finally:
        worker.terminate()


def rows_drawn(page: Page) -> int:
    return int(page.locator("#training-curve").get_attribute("data-rows") or 0)


def test_the_training_curve_is_drawn_live_on_the_job_page(
    page: Page, site: Site, trainer: Worker
) -> None:
    # twenty rollouts: a row of the curve at each one
    scenario = {"preset": "alonso-kirkegaard", "seed": 5, "robots": {"policy": "ppo"},
                "learning": {"decisions": 20 * ROLLOUT}, "evaluation": {"worlds": 2}}  # fmt: skip
    job = httpx.post(f"{site.url}/jobs", json=scenario).json()
    page.goto(f"{site.url}/ui/jobs/{job['id']}")
    expect(page.locator("#job-status")).to_have_text("running", timeout=FIRST_JOB_S * 1000)
    curve = page.locator("#training-curve")
    rows = "Number(document.getElementById('training-curve').dataset.rows)"
    page.wait_for_function(f"{rows} >= 1", timeout=FIRST_JOB_S * 1000)
    first = rows_drawn(page)
    # the page was not reloaded: the rows came with the live progress, and keep coming
    page.wait_for_function(f"{rows} >= {max(3, first + 1)}", timeout=60_000)
    assert page.locator("#job-status").text_content() == "running"
    drawn = int(curve.get_attribute("data-points") or 0)
    assert drawn >= 1  # rows whose episodes reached or missed a cell are points
    assert curve.locator("circle").count() == drawn
    assert curve.locator("text", has_text="decisions trained").count() == 1
    live = httpx.get(f"{site.url}/jobs/{job['id']}").json()["progress"]["training_curve"]
    assert len(live) >= rows_drawn(page) >= 3
    assert all(row["decisions"] % ROLLOUT == 0 for row in live)
    screenshot(page, "training-curve-live")

    assert httpx.post(f"{site.url}/jobs/{job['id']}/cancel", headers=JSON).status_code == 200
    expect(page.locator("#job-status")).to_have_text("cancelled", timeout=30_000)
    # the page reloads to show the end (no live progress any more) and keeps the rows trained
    expect(page.locator("#live-note")).to_have_count(0, timeout=10_000)
    # the reloaded page's script draws the kept rows once it has run
    page.wait_for_function(
        f"Number(document.getElementById('training-curve').dataset.rows) >= {len(live)}",
        timeout=10_000,
    )
    assert rows_drawn(page) >= len(live)
