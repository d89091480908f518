"""The dashboard of an API with keys, in a real browser: a person is sent to the login page,
pastes a key, and then runs and watches a job as without keys; another key does not see it."""

from __future__ import annotations

import re
from collections.abc import Iterator

import httpx
import pytest
from playwright.sync_api import Page, expect

from tests.browser.conftest import Site, screenshot
from tests.conftest import api_with_worker
from tests.service.test_security import KEY_A, KEY_B, bearer

pytestmark = pytest.mark.timeout(180)


@pytest.fixture(scope="module")
def site(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Site]:
    """An API with two keys, and a worker, over a SQLite file."""
    keys = f"{KEY_A},{KEY_B}"
    directory = tmp_path_factory.mktemp("keyed-dashboard")
    with api_with_worker(directory, NANONAV_API_KEYS=keys) as (api, url):
        yield Site(url=api.url, database_url=url, directory=directory)
    assert KEY_A not in api.text() and KEY_B not in api.text()


def log_in(page: Page, site: Site, key: str) -> None:
    page.goto(site.url + "/")
    page.wait_for_url(re.compile(r"/ui/login\?next=%2F$"))
    page.fill("#key", key)
    page.click("button[type=submit]")
    page.wait_for_url(site.url + "/")


def test_a_person_logs_in_with_a_key_and_runs_and_watches_a_job(page: Page, site: Site) -> None:
    page.goto(site.url + "/ui/jobs")
    page.wait_for_url(re.compile(r"/ui/login\?next=%2Fui%2Fjobs$"))
    page.fill("#key", KEY_A[::-1])
    page.click("button[type=submit]")
    expect(page.locator("#form-errors")).to_contain_text("not one this API accepts")
    screenshot(page, "login-refused")
    page.fill("#key", KEY_A)
    page.click("button[type=submit]")
    page.wait_for_url(site.url + "/ui/jobs")
    assert KEY_A not in page.content()
    assert page.evaluate("document.cookie") == ""  # HttpOnly: no script reads the key

    page.goto(site.url + "/")
    page.fill("input[name='learning.episodes']", "3")
    page.fill("input[name='learning.max_steps']", "100")
    page.fill("input[name='evaluation.worlds']", "2")
    page.click("button[type=submit]")
    page.wait_for_url(re.compile(r"/ui/jobs/\d+$"))
    job_id = page.url.rsplit("/", 1)[1]
    expect(page.locator("#job-status")).to_have_text("succeeded", timeout=120_000)
    expect(page.locator("#table-1 tbody tr")).to_have_count(8)
    screenshot(page, "job-with-key")
    assert httpx.get(f"{site.url}/jobs/{job_id}", headers=bearer(KEY_A)).status_code == 200
    assert httpx.get(f"{site.url}/jobs/{job_id}", headers=bearer(KEY_B)).status_code == 404
    assert httpx.get(f"{site.url}/jobs/{job_id}").status_code == 401


def test_another_key_does_not_see_the_job(page: Page, site: Site) -> None:
    job = httpx.post(f"{site.url}/jobs", json={}, headers=bearer(KEY_A)).json()
    log_in(page, site, KEY_B)
    page.goto(f"{site.url}/ui/jobs/{job['id']}")
    expect(page.locator("h1")).to_have_text("Not found")
    page.goto(f"{site.url}/ui/jobs")
    assert f"/ui/jobs/{job['id']}" not in page.content()
    httpx.post(f"{site.url}/jobs/{job['id']}/cancel", headers=bearer(KEY_A))
    page.click("#logout")
    page.wait_for_url(re.compile(r"/ui/login"))
    page.goto(f"{site.url}/ui/jobs")
    page.wait_for_url(re.compile(r"/ui/login\?next="))


def test_a_login_never_leaves_the_site_whatever_next_says(page: Page, site: Site) -> None:
    for target in ("/%5Cevil.example/x", "//evil.example/x", "/%09/evil.example/x"):
        page.context.clear_cookies()
        page.goto(f"{site.url}/ui/login?next={target}")
        page.fill("#key", KEY_A)
        page.click("button[type=submit]")
        page.wait_for_url(site.url + "/")
    page.goto(f"{site.url}/ui/login?next=%2Fui%2Fstudies")
    page.fill("#key", KEY_A)
    page.click("button[type=submit]")
    page.wait_for_url(site.url + "/ui/studies")
