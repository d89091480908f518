"""A real browser (Playwright driving Debian's Chromium, headless) against a real API process
and a real worker over a SQLite file. Chromium is what `.ci/run` installs; on a machine without
it these tests are skipped with the reason, except in CI (``CI=true``), where that fails.

Every request to another host is refused, so the pages are shown to work offline. Screenshots
go to ``var/screenshots`` (or ``NANONAV_SCREENSHOTS``)."""

from __future__ import annotations

import os
import shutil
from collections.abc import Generator, Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest
from playwright.sync_api import Browser, Page, Route, sync_playwright

from tests.conftest import api_with_worker, in_ci

CHROMIUM = os.environ.get("NANONAV_CHROMIUM", "/usr/bin/chromium")
# The flags a sandboxed machine needs: no sandbox as root, no GPU, no calls home.
CHROMIUM_ARGS = ["--no-sandbox", "--disable-gpu", "--disable-background-networking",
                 "--disable-component-update", "--disable-sync", "--no-first-run"]  # fmt: skip
SCREENSHOTS = Path(
    os.environ.get("NANONAV_SCREENSHOTS", Path(__file__).resolve().parents[2] / "var/screenshots")
)


# What a failed test's report shows of the site's API and worker logs: their last lines.
LOG_TAIL_LINES = 60


@dataclass
class Site:
    url: str
    database_url: str
    directory: Path

    def logs(self) -> dict[str, str]:
        """The last lines of the API's and the worker's logs."""
        tails = {}
        for name in ("api.log", "worker.log"):
            path = self.directory / name
            lines = path.read_text(errors="replace").splitlines() if path.exists() else []
            tails[name] = "\n".join(lines[-LOG_TAIL_LINES:])
        return tails


@pytest.fixture(scope="module")
def site(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Site]:
    directory = tmp_path_factory.mktemp("dashboard")
    with api_with_worker(directory) as (api, url):
        yield Site(url=api.url, database_url=url, directory=directory)


@pytest.hookimpl(wrapper=True)
def pytest_runtest_makereport(
    item: pytest.Item, call: pytest.CallInfo[None]
) -> Generator[None, pytest.TestReport, pytest.TestReport]:
    """A failed test's report carries what the site's processes logged last, so a job that
    never finished says why (the processes and their logs are gone once the run ends)."""
    report: pytest.TestReport = yield
    site = getattr(item, "funcargs", {}).get("site")
    if report.failed and isinstance(site, Site):
        for name, tail in site.logs().items():
            report.sections.append((f"{name} (last {LOG_TAIL_LINES} lines)", tail))
    return report


def require_chromium() -> None:
    """Skip without Chromium, with the reason; in CI, fail instead."""
    if shutil.which(CHROMIUM) is None and not Path(CHROMIUM).exists():
        if in_ci():
            pytest.fail(f"Chromium must be installed in CI ({CHROMIUM}); .ci/run installs it")
        pytest.skip(f"no Chromium at {CHROMIUM} (apt-get install chromium)")


@pytest.fixture(scope="module")
def browser() -> Iterator[Browser]:
    require_chromium()
    with sync_playwright() as playwright:
        launched = playwright.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        yield launched
        launched.close()


@pytest.fixture
def page(browser: Browser, site: Site) -> Iterator[Page]:
    context = browser.new_context(viewport={"width": 1280, "height": 900})
    opened = context.new_page()
    problems: list[str] = []
    opened.on("pageerror", lambda error: problems.append(str(error)))

    def local_only(route: Route) -> None:
        if route.request.url.startswith(site.url):
            route.continue_()
        else:
            problems.append(f"request to another host: {route.request.url}")
            route.abort()

    opened.route("**/*", local_only)
    yield opened
    context.close()
    assert problems == [], problems


def screenshot(page: Page, name: str) -> Path:
    SCREENSHOTS.mkdir(parents=True, exist_ok=True)
    path = SCREENSHOTS / f"{name}.png"
    page.screenshot(path=str(path), full_page=True)
    return path
