"""What a person does at the dashboard, in a real browser: run a job and watch it, read its
results, turn its paths in 3-D, fix a field the server refused, cancel, launch a study and read
its table, browse jobs, evaluate a policy sent from elsewhere, and read the API page, all with no
request leaving the machine."""

from __future__ import annotations

import re
import time
from typing import Any

import httpx
import numpy as np
import pytest
from playwright.sync_api import Dialog, Page, Route, expect
from playwright.sync_api import Error as BrowserError

from nanonav.engine import qlearning
from tests.browser.conftest import Site, screenshot

pytestmark = pytest.mark.timeout(180)

LONG = {"space": {"size": 1000}, "robots": {"count": 50, "policy": "random"},
        "learning": {"episodes": 900, "max_steps": 20_000}}  # fmt: skip

# Logs every state a page's event stream hears, before the page's own handlers run.
HEARD = """
const Heard = window.EventSource;
window.EventSource = class extends Heard {
  constructor(...args) {
    super(...args);
    for (const name of ["progress", "status", "message"]) {
      this.addEventListener(name, (event) => console.log(`heard ${event.data}`));
    }
  }
};
"""


def wait_for_images(page: Page) -> list[dict[str, object]]:
    """Load every picture on the page (they load lazily) and report each one's size."""
    page.evaluate("document.querySelectorAll('img').forEach((img) => { img.loading = 'eager'; })")
    page.wait_for_function(
        "Array.from(document.images).every((img) => img.complete)", timeout=60_000
    )
    found: list[dict[str, object]] = page.evaluate(
        "Array.from(document.images).map((img) => ({src: img.src, width: img.naturalWidth}))"
    )
    return found


def test_a_job_submitted_through_the_form_runs_live_and_shows_its_results(
    page: Page, site: Site
) -> None:
    page.goto(site.url + "/")
    page.select_option("select[name=preset]", "paper-swarm")
    page.fill("input[name='learning.episodes']", "5000")
    page.fill("input[name='learning.max_steps']", "400")
    page.fill("input[name='evaluation.worlds']", "3")
    page.fill("input[name=seed]", "5")
    screenshot(page, "new-job")
    page.click("button[type=submit]")
    page.wait_for_url(re.compile(r"/ui/jobs/\d+$"))
    job_id = page.url.rsplit("/", 1)[1]
    scenario = httpx.get(f"{site.url}/jobs/{job_id}").json()["scenario"]
    assert scenario["seed"] == 5 and scenario["robots"]["count"] == 15
    assert scenario["learning"]["episodes"] == 5000

    seen: set[str] = set()
    deadline = time.monotonic() + 120
    while True:
        assert time.monotonic() < deadline, "the job did not finish"
        # read in one step: the progress card goes when the job ends, and a locator that
        # counted it a moment ago would then wait for it
        try:
            text, done = page.evaluate(
                "[document.getElementById('progress-text')?.innerText ?? null,"
                " document.getElementById('table-1') !== null]"
            )
        except BrowserError as error:
            # the page reloads itself when the job ends; a read that meets the reload is retried
            if "context was destroyed" not in str(error):
                raise
            page.wait_for_load_state()
            continue
        if done:
            break
        if text is not None:
            seen.add(text)
        page.wait_for_timeout(100)
    moving = [s for s in seen if not s.startswith(("0%", "100%"))]
    assert moving, f"progress never moved between 0 and 100%: {seen}"
    expect(page.locator("#job-status")).to_have_text("succeeded")
    rows = page.locator("#table-1 tbody tr")
    expect(rows).to_have_count(8)
    expect(rows.first).to_contain_text("Total Steps")
    images = wait_for_images(page)
    assert len(images) >= 7
    assert all(int(str(image["width"])) > 0 for image in images), images
    screenshot(page, "job")

    page.click("#open-3d")
    page.wait_for_selector("#view3d .main-svg", timeout=30_000)
    page.locator("#step").fill("40")
    page.dispatch_event("#step", "input")
    assert page.locator("#step-value").inner_text() != "0"
    screenshot(page, "job-3d")


def test_a_refused_field_is_shown_next_to_it(page: Page, site: Site) -> None:
    page.goto(site.url + "/")
    page.fill("input[name='robots.count']", "0")
    page.click("button[type=submit]")
    error = page.locator("input[name='robots.count'] + .field-error")
    expect(error).to_contain_text("greater than or equal to 1")
    expect(page.locator("input[name='robots.count']")).to_have_attribute("aria-invalid", "true")
    assert page.url.rstrip("/") == site.url
    page.click("#json-details summary")
    page.fill("#scenario-json", '{"robots": {"count": 2, "speed": -1}}')
    page.click("button[type=submit]")
    expect(page.locator("#form-errors")).to_contain_text("#/robots/speed")
    screenshot(page, "new-job-refused")


def test_a_running_job_is_cancelled_from_its_page(page: Page, site: Site) -> None:
    job = httpx.post(f"{site.url}/jobs", json=LONG).json()
    page.goto(f"{site.url}/ui/jobs/{job['id']}")
    expect(page.locator("#job-status")).to_have_text("running", timeout=60_000)
    asked: list[str] = []

    def answer(dialog: Dialog, accept: bool) -> None:
        asked.append(dialog.message)
        if accept:
            dialog.accept()
        else:
            dialog.dismiss()

    page.once("dialog", lambda dialog: answer(dialog, False))
    page.click("#cancel")  # asked, and not confirmed: the job runs on
    page.wait_for_timeout(1_000)
    assert httpx.get(f"{site.url}/jobs/{job['id']}").json()["cancel_requested"] is False
    page.once("dialog", lambda dialog: answer(dialog, True))
    page.click("#cancel")
    expect(page.locator("#job-status")).to_have_text("cancelled", timeout=30_000)
    assert asked == [f"Cancel job #{job['id']}? It stops without an evaluation; the training "
                     "episodes it finished are kept."] * 2  # fmt: skip
    assert httpx.get(f"{site.url}/jobs/{job['id']}").json()["status"] == "cancelled"


def test_a_study_is_cancelled_from_its_page_once_confirmed(page: Page, site: Site) -> None:
    study = {"name": "to cancel", "base": LONG, "grid": {"robots.policy": ["random"]},
             "seeds": [1, 2]}  # fmt: skip
    study_id = httpx.post(f"{site.url}/studies", json=study).json()["id"]
    page.goto(f"{site.url}/ui/studies/{study_id}")
    expect(page.locator("#cancel")).to_be_visible()
    page.once("dialog", lambda dialog: dialog.dismiss())
    page.click("#cancel")  # not confirmed: nothing is cancelled
    page.wait_for_timeout(1_000)
    assert httpx.get(f"{site.url}/studies/{study_id}").json()["status"] in ("queued", "running")
    asked: list[str] = []

    def accept(dialog: Dialog) -> None:
        asked.append(dialog.message)
        dialog.accept()

    page.once("dialog", accept)
    page.click("#cancel")
    expect(page.locator("#delete")).to_be_visible(timeout=60_000)  # shown once it has ended
    assert httpx.get(f"{site.url}/studies/{study_id}").json()["status"] == "cancelled"
    assert asked and asked[0].startswith(f"Cancel study #{study_id}?")


def test_a_studys_failed_jobs_are_retried_from_its_page(page: Page, site: Site) -> None:
    # no room for 300 obstacles: that point fails in the engine, and fails again when retried
    crowded = {"robots": {"count": 10000}, "obstacles": {"radius": 3.0},
               "learning": {"episodes": 0, "max_steps": 5}}  # fmt: skip
    study = {"name": "to retry", "base": crowded, "grid": {"obstacles.count": [0, 300]},
             "seeds": [1]}  # fmt: skip
    study_id = httpx.post(f"{site.url}/studies", json=study).json()["id"]
    page.goto(f"{site.url}/ui/studies/{study_id}")
    expect(page.locator("#study-status")).to_have_text("failed", timeout=60_000)
    page.reload()
    expect(page.locator("#retry")).to_have_text("Retry its 1 failed job")
    jobs = httpx.get(f"{site.url}/jobs", params={"study": study_id}).json()["jobs"]
    [failed] = [job for job in jobs if job["status"] == "failed"]
    with page.expect_navigation():  # the page reloads to follow the job queued again
        page.click("#retry")
    deadline = time.monotonic() + 60
    while (again := httpx.get(f"{site.url}/jobs/{failed['id']}").json())["status"] != "failed":
        assert time.monotonic() < deadline, again
        time.sleep(0.2)
    assert again["finished_at"] > failed["finished_at"]  # it ran again, and failed once more
    assert again["attempts"] == 1  # counted anew
    expect(page.locator("#study-status")).to_have_text("failed", timeout=60_000)


def test_a_link_followed_as_the_job_ends_is_not_undone_by_the_page(page: Page, site: Site) -> None:
    # A job's page reloads itself when the job ends, to show the results. A user who has just
    # followed a link (here "Run again") must not be taken back: the reload would cancel the
    # navigation still under way (a slow server; once 90 s in CI). The new page's answer is held
    # until the job has ended and the old page has heard it; the old page is not readable while
    # a navigation is under way, so what it hears is logged to the console.
    page.add_init_script(HEARD)
    job = httpx.post(f"{site.url}/jobs", json=LONG).json()
    page.goto(f"{site.url}/ui/jobs/{job['id']}")
    expect(page.locator("#job-status")).to_have_text(re.compile("queued|running"))
    held: list[Route] = []
    page.route(re.compile(rf"/\?from={job['id']}$"), lambda route: held.append(route))
    page.click("#run-again", no_wait_after=True)  # its navigation waits for the held answer
    with page.expect_console_message(lambda m: '"cancelled"' in m.text, timeout=30_000):
        assert httpx.post(f"{site.url}/jobs/{job['id']}/cancel", json={}).status_code == 200
    page.wait_for_timeout(1_000)  # more than the page waits before it reloads
    assert len(held) == 1
    held[0].continue_()
    page.wait_for_url(re.compile(rf"/\?from={job['id']}$"), wait_until="domcontentloaded")
    expect(page.locator("#from-job")).to_contain_text(f"job #{job['id']}")


QUICK = {"robots": {"count": 1}, "learning": {"episodes": 1, "max_steps": 40},
         "evaluation": {"worlds": 1}}  # fmt: skip


def test_a_finished_job_and_study_are_deleted_from_their_pages(page: Page, site: Site) -> None:
    job_id = httpx.post(f"{site.url}/jobs", json=QUICK).json()["id"]
    page.goto(f"{site.url}/ui/jobs/{job_id}")
    expect(page.locator("#job-status")).to_have_text("succeeded", timeout=60_000)
    # the page reloads with its results and the button, enabled once its script can take a click
    expect(page.locator("#delete")).to_be_enabled(timeout=30_000)
    page.once("dialog", lambda dialog: dialog.dismiss())
    page.click("#delete")
    expect(page.locator("#delete")).to_be_enabled()
    assert httpx.get(f"{site.url}/jobs/{job_id}").status_code == 200  # not confirmed: kept
    page.once("dialog", lambda dialog: dialog.accept())
    page.click("#delete")
    page.wait_for_url(re.compile(r"/ui/jobs$"))
    assert httpx.get(f"{site.url}/jobs/{job_id}").status_code == 404

    study = {"name": "to delete", "base": QUICK, "grid": {"robots.policy": ["gradient"]},
             "seeds": [1]}  # fmt: skip
    study_id = httpx.post(f"{site.url}/studies", json=study).json()["id"]
    page.goto(f"{site.url}/ui/studies/{study_id}")
    expect(page.locator("#delete")).to_be_visible(timeout=60_000)  # shown once it has ended
    expect(page.locator("#delete")).to_be_enabled()
    page.once("dialog", lambda dialog: dialog.accept())
    page.click("#delete")
    page.wait_for_url(re.compile(r"/ui/studies$"))
    assert httpx.get(f"{site.url}/studies/{study_id}").status_code == 404


def test_the_study_form_starts_as_the_first_study_tutorial_fills_it_in(
    page: Page, site: Site
) -> None:
    """docs/tutorials/first-study.md: paper-single, 20 training episodes, 5 seeds, the policy
    swept over gradient and q_learning (the rule first: the baseline), compared, nothing else."""
    page.goto(site.url + "/ui/studies/new")
    expect(page.locator("select[name='base.preset']")).to_have_value("paper-single")
    expect(page.locator("input[name='base.learning.episodes']")).to_have_value("20")
    expect(page.locator("input[name=replicates]")).to_have_value("5")
    expect(page.locator("select[name=key1]")).to_have_value("robots.policy")
    expect(page.locator("input[name=values1]")).to_have_value("gradient, q_learning")
    expect(page.locator("select[name=key2]")).to_have_value("")
    expect(page.locator("select[name=compare]")).to_have_value("1")


def test_a_study_launched_from_the_form_fills_in_its_table(page: Page, site: Site) -> None:
    page.goto(site.url + "/ui/studies/new")
    page.fill("input[name=name]", "browser study")
    page.fill("input[name='base.learning.episodes']", "3")
    page.fill("input[name=replicates]", "3")
    page.fill("input[name=values1]", "q_learning, gradient")
    page.select_option("select[name=key2]", "obstacles.count")
    page.fill("input[name=values2]", "0, 20")
    screenshot(page, "new-study")
    page.click("button[type=submit]")
    page.wait_for_url(re.compile(r"/ui/studies/\d+$"))
    expect(page.locator("#study-status")).to_have_text("succeeded", timeout=120_000)
    expect(page.locator("#points-table tbody tr")).to_have_count(4)
    expect(page.locator("#comparisons-table tbody tr")).to_have_count(2)
    first_row = page.locator("#points-table tbody tr").first
    expect(first_row).to_contain_text("q_learning")
    expect(first_row).to_contain_text("3/3")
    images = wait_for_images(page)
    # a picture for each shown metric, the learning curves and the learned policies
    assert len(images) == 5 and all(int(str(i["width"])) > 0 for i in images), images
    assert any("/plots/policies.png" in str(i["src"]) for i in images), images
    study_id = page.url.rsplit("/", 1)[1]
    table = httpx.get(f"{site.url}/studies/{study_id}/results.csv").text
    assert len(table.splitlines()) == 1 + 12
    # the comparisons' own table, linked; each n says what difference its seeds resolve
    link = page.locator("a[href$='/comparisons.csv']")
    expect(link).to_have_count(1)
    compared = httpx.get(f"{site.url}{link.get_attribute('href')}").text.splitlines()
    assert compared[0].endswith("p_value,p_holm,holm_comparisons,resolvable")
    assert len(compared) > 2  # two obstacle counts, each metric a row
    resolves = page.locator("#comparisons-table span.n[title]").first.get_attribute("title")
    assert resolves is not None and "seeds find a mean difference of" in resolves, resolves
    screenshot(page, "study")


def test_a_study_that_ends_while_its_table_is_on_the_way_shows_its_end(
    page: Page, site: Site
) -> None:
    """The page asks for its table each time a job ends. When the last one ends while the table
    asked for before is still on its way (a slow server), that ask is not dropped: it follows,
    and the page says the study succeeded rather than 'running' for good."""
    held: list[tuple[Route, Any]] = []

    def hold_the_first(route: Route) -> None:
        if held:
            route.continue_()
        else:  # read now, while the study runs; handed to the page once it has ended
            held.append((route, route.fetch()))

    page.route(re.compile(r"/ui/studies/\d+/results$"), hold_the_first)
    # four jobs of most of a second each: the page reads its first table while they run
    base = {"robots": {"policy": "random"}, "learning": {"episodes": 100, "max_steps": 2000},
            "evaluation": {"worlds": 1}}  # fmt: skip
    study = {"name": "slow table", "base": base, "grid": {"robots.count": [20, 21]},
             "replicates": 2}  # fmt: skip
    study_id = httpx.post(f"{site.url}/studies", json=study).json()["id"]
    page.goto(f"{site.url}/ui/studies/{study_id}")
    deadline = time.monotonic() + 120
    while not held or httpx.get(f"{site.url}/studies/{study_id}").json()["status"] != "succeeded":
        assert time.monotonic() < deadline, "the study did not succeed"
        page.wait_for_timeout(100)
    expect(page.locator("#delete-row")).to_be_visible()  # the page heard that it ended
    route, table = held[0]
    assert 'data-status="succeeded"' not in table.text(), "the table was read after the end"
    route.fulfill(response=table)
    expect(page.locator("#study-status")).to_have_text("succeeded", timeout=10_000)
    expect(page.locator("#points-table tbody tr")).to_have_count(2)


def test_jobs_are_browsed_and_filtered(page: Page, site: Site) -> None:
    for policy in ("gradient", "rule"):
        httpx.post(f"{site.url}/jobs", json={"robots": {"policy": policy},
                                             "learning": {"episodes": 0, "max_steps": 50},
                                             "evaluation": {"worlds": 1}})  # fmt: skip
    page.goto(site.url + "/ui/jobs")
    page.select_option("select[name=policy]", "gradient")
    page.click(".filters button")
    page.wait_for_url(re.compile(r"policy=gradient"))
    policies = page.locator("table.list tbody tr td:nth-child(6)").all_inner_texts()
    assert policies and set(policies) == {"gradient"}
    screenshot(page, "jobs")


def test_the_api_page_works_offline(page: Page, site: Site) -> None:
    page.goto(site.url + "/docs")
    expect(page.locator(".swagger-ui .opblock").first).to_be_visible(timeout=30_000)
    assert page.locator(".swagger-ui .opblock").count() >= 15
    screenshot(page, "docs")


def finished(site: Site, kind: str, body: dict[str, Any]) -> int:
    """The id of a new job or study, once it has succeeded."""
    made = httpx.post(f"{site.url}/{kind}", json=body).json()["id"]
    deadline = time.monotonic() + 60
    while httpx.get(f"{site.url}/{kind}/{made}").json()["status"] != "succeeded":
        assert time.monotonic() < deadline, f"{kind} {made} did not succeed"
        time.sleep(0.1)
    return int(made)


def test_pasted_json_sets_the_fields_and_the_preset_menu(page: Page, site: Site) -> None:
    page.goto(site.url + "/")
    page.click("#json-details summary")
    page.fill("#scenario-json", '{"preset": "paper-swarm", "seed": 3, "robots": {"count": 4}}')
    expect(page.locator("select[name=preset]")).to_have_value("paper-swarm")
    expect(page.locator("input[name=seed]")).to_have_value("3")
    expect(page.locator("input[name='robots.count']")).to_have_value("4")
    page.fill("#scenario-json", "{}")
    expect(page.locator("select[name=preset]")).to_have_value("")
    expect(page.locator("input[name=seed]")).to_have_value("")


def test_run_again_repeats_a_job_with_its_seed(page: Page, site: Site) -> None:
    job = httpx.post(f"{site.url}/jobs", json={**QUICK, "preset": "paper-single", "seed": 11})
    job_id = job.json()["id"]
    page.goto(f"{site.url}/ui/jobs/{job_id}")
    page.click("#run-again")
    # the form's page, not its last resource: the server may still be drawing the job's
    # pictures the page before asked for, when the whole suite shares the two cores
    page.wait_for_url(re.compile(rf"/\?from={job_id}$"), wait_until="domcontentloaded",
                      timeout=90_000)  # fmt: skip
    expect(page.locator("#from-job")).to_contain_text("seed 11")
    expect(page.locator("select[name=preset]")).to_have_value("paper-single")
    expect(page.locator("input[name=seed]")).to_have_value("11")
    screenshot(page, "new-job-again")
    page.click("button[type=submit]")
    page.wait_for_url(re.compile(r"/ui/jobs/\d+$"))
    again = page.url.rsplit("/", 1)[1]
    assert again != str(job_id)
    scenario = httpx.get(f"{site.url}/jobs/{again}").json()["scenario"]
    assert scenario == job.json()["scenario"]


PICTURES = re.compile(r"/jobs/\d+/(plots/|heatmap)")


def test_a_picture_says_drawing_until_it_loads_and_opens_full_size(page: Page, site: Site) -> None:
    job_id = finished(site, "jobs", QUICK)
    held: list[Route] = []
    page.route(PICTURES, lambda route: held.append(route))
    page.goto(f"{site.url}/ui/jobs/{job_id}")
    first = page.locator(".pictures a.picture").first
    expect(first.locator(".drawing")).to_be_visible()
    expect(first.locator(".drawing")).to_have_text("drawing…")
    src = first.locator("img").get_attribute("src")
    assert src and first.get_attribute("href") == src and first.get_attribute("target") == "_blank"
    screenshot(page, "job-drawing")
    page.unroute(PICTURES)
    for route in held:
        route.continue_()
    wait_for_images(page)
    expect(page.locator(".pictures a.picture:not(.loaded)")).to_have_count(0)
    expect(first.locator(".drawing")).to_be_hidden()
    screenshot(page, "job-drawn")


def assert_study_tables_fit(page: Page) -> None:
    """Both of a study page's tables are as wide as the room they are given, or narrower."""
    widths = page.evaluate(
        "Array.from(document.querySelectorAll('.study-table')).map((table) =>"
        " [table.id, table.scrollWidth, table.parentElement.clientWidth])"
    )
    assert len(widths) == 2 and all(inside <= room for _, inside, room in widths), widths


def test_a_studys_tables_fit_a_1400_pixel_window(page: Page, site: Site) -> None:
    base = {**QUICK, "learning": {"episodes": 1, "max_steps": 1200}}
    grid = {"robots.policy": ["q_learning", "gradient"],
            "biomarker.detection_threshold": [0, 0.005]}  # fmt: skip
    study = {"name": "fits", "base": base, "grid": grid, "seeds": [1, 2],
             "compare": "robots.policy"}  # fmt: skip
    study_id = finished(site, "studies", study)
    page.set_viewport_size({"width": 1400, "height": 900})
    page.goto(f"{site.url}/ui/studies/{study_id}")
    expect(page.locator("#comparisons-table tbody tr")).to_have_count(2)
    # its q_learning points learn: the page shows what they learned
    expect(page.locator("img[src*='/plots/policies.png']")).to_have_count(1)
    assert_study_tables_fit(page)
    screenshot(page, "study-1400")


def test_a_policy_is_evaluated_from_the_policies_page(page: Page, site: Site) -> None:
    states, actions = qlearning.labels("directions", "none")
    body = {"name": "trained elsewhere", "states": states, "actions": actions,
            "values": np.eye(len(states), len(actions)).tolist()}  # fmt: skip
    sent = httpx.post(f"{site.url}/policies", json=body).json()
    page.goto(f"{site.url}/ui/policies")
    expect(page.locator("#policies")).to_contain_text("trained elsewhere")
    screenshot(page, "policies")
    page.click(f"a[href='/?policy={sent['id']}']")
    page.wait_for_url(re.compile(rf"/\?policy={sent['id']}$"), wait_until="domcontentloaded")
    expect(page.locator("#from-policy")).to_contain_text(sent["policy_from"])
    expect(page.locator("select[name='learning.actions']")).to_have_value("directions")
    expect(page.locator("input[name='learning.episodes']")).to_have_value("0")
    page.fill("input[name=seed]", "4")
    page.fill("input[name='learning.max_steps']", "60")
    page.fill("input[name='evaluation.worlds']", "2")
    page.click("button[type=submit]")
    page.wait_for_url(re.compile(r"/ui/jobs/\d+$"))
    job_id = page.url.rsplit("/", 1)[1]
    scenario = httpx.get(f"{site.url}/jobs/{job_id}").json()["scenario"]
    assert scenario["policy_from"] == sent["policy_from"] and scenario["seed"] == 4
    assert scenario["learning"]["episodes"] == 0
    assert scenario["learning"]["actions"] == "directions"


def test_a_swarm_studys_comparisons_can_be_read_to_their_right_edge_at_1400_pixels(
    page: Page, site: Site
) -> None:
    base = {**QUICK, "robots": {"count": 3, "exclusion": True}, "cells": {"count": 2,
            "capacity": 1}, "learning": {"episodes": 1, "max_steps": 300}}  # fmt: skip
    grid = {"robots.policy": ["q_learning", "gradient", "random"],
            "communication.model": ["none", "broadcast"],
            "biomarker.detection_threshold": [0, 0.005]}  # fmt: skip
    study = {"name": "a wide swarm table", "base": base, "grid": grid, "seeds": [1, 2],
             "compare": "robots.policy"}  # fmt: skip
    study_id = finished(site, "studies", study)
    page.set_viewport_size({"width": 1400, "height": 900})
    page.goto(f"{site.url}/ui/studies/{study_id}")
    table = page.locator("#comparisons-table")
    expect(table.locator("tbody tr")).to_have_count(8)
    assert table.locator("thead th").count() >= 14  # the swarm's metrics: a wide table
    # both tables are whole in the window, their last column in view without scrolling
    for name in ("points-table", "comparisons-table"):
        last = page.locator(f"#{name} thead th").last
        edge = last.evaluate("(cell) => cell.getBoundingClientRect().right")
        assert 0 < edge <= 1400, (name, edge)
    assert_study_tables_fit(page)
    assert page.evaluate("document.documentElement.scrollWidth") <= 1400
    screenshot(page, "swarm-study-1400")


def test_a_right_to_left_override_in_a_name_turns_nothing_after_it(page: Page, site: Site) -> None:
    """A study named with U+202E (right-to-left override) once turned the rest of its heading
    around: the status after the name was drawn to its left. The name is isolated (``bdi``),
    so what follows it keeps its order, on the study's page and in the list of studies."""
    name = "tumour \u202eevil"
    study = {"name": name, "base": QUICK, "grid": {"robots.policy": ["gradient"]}, "seeds": [1]}
    study_id = httpx.post(f"{site.url}/studies", json=study).json()["id"]
    page.goto(f"{site.url}/ui/studies/{study_id}")
    expect(page.locator("h1")).to_contain_text(name)
    # the right edge of the name's text as drawn, and where the status after it begins
    name_right = page.evaluate(
        """() => {
          const walker = document.createTreeWalker(document.querySelector('h1'),
                                                   NodeFilter.SHOW_TEXT);
          while (walker.nextNode()) {
            if (walker.currentNode.data.includes('\\u202e')) {
              const range = document.createRange();
              range.selectNodeContents(walker.currentNode);
              return range.getBoundingClientRect().right;
            }
          }
          return null;
        }"""
    )
    status = page.locator("#study-status").bounding_box()
    assert name_right is not None and status is not None
    assert status["x"] >= name_right, (status, name_right)
    page.goto(f"{site.url}/ui/studies")
    row = page.locator("tr", has_text="evil").first
    assert row.locator("bdi").first.inner_text() == name
