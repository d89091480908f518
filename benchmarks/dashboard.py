"""How fast the dashboard's pages paint, in a real browser (Debian's Chromium, headless), over
real API and worker processes on SQLite.

Prints the time to first contentful paint and to the load event of a finished job's page and of
a finished 100-job study's page (median of a few fresh visits each, no cache).

    .venv/bin/python benchmarks/dashboard.py [--visits 5] [--chromium /usr/bin/chromium]
"""

from __future__ import annotations

import argparse
import importlib.util
import statistics
import sys
import time
from pathlib import Path

from playwright.sync_api import sync_playwright

# The service benchmark's processes: loaded from its path (``service`` is the API package).
_SPEC = importlib.util.spec_from_file_location(
    "service_benchmark", Path(__file__).resolve().parent / "service.py"
)
assert _SPEC is not None and _SPEC.loader is not None
service_benchmark = importlib.util.module_from_spec(_SPEC)
sys.modules["service_benchmark"] = service_benchmark
_SPEC.loader.exec_module(service_benchmark)

CHROMIUM_ARGS = ["--no-sandbox", "--disable-gpu", "--disable-background-networking",
                 "--disable-component-update", "--disable-sync", "--no-first-run"]  # fmt: skip
# Paint entries are delivered to an observer, buffered since navigation started.
PAINT = """() => new Promise((resolve) => {
  new PerformanceObserver((list, observer) => {
    const paint = list.getEntriesByName('first-contentful-paint')[0];
    if (!paint) return;
    observer.disconnect();
    const navigation = performance.getEntriesByType('navigation')[0];
    resolve([paint.startTime, navigation ? navigation.loadEventEnd : null]);
  }).observe({type: 'paint', buffered: true});
})"""


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--visits", type=int, default=5)
    parser.add_argument("--chromium", default="/usr/bin/chromium")
    parser.add_argument("--study-seeds", type=int, default=50, help="x 2 policies = jobs")
    args = parser.parse_args(argv)
    with service_benchmark.service(2) as running:
        client = running.client
        job = client.post("/jobs", json={"preset": "paper-swarm"}).json()["id"]
        study = client.post("/studies", json={
            "name": "benchmark", "base": {"preset": "paper-single"},
            "grid": {"robots.policy": ["q_learning", "gradient"]},
            "replicates": args.study_seeds, "compare": "robots.policy",
        }).json()["id"]  # fmt: skip
        service_benchmark.wait_all(client, [job])
        while client.get(f"/studies/{study}").json()["status"] in {"queued", "running"}:
            time.sleep(0.2)
        base = str(client.base_url).rstrip("/")
        pages = {
            "job page (paper-swarm, 20 evaluation worlds)": f"{base}/ui/jobs/{job}",
            f"study page ({2 * args.study_seeds} jobs)": f"{base}/ui/studies/{study}",
        }
        with sync_playwright() as playwright:
            browser = playwright.chromium.launch(executable_path=args.chromium, args=CHROMIUM_ARGS)
            for name, url in pages.items():
                paints, loads = [], []
                for _ in range(args.visits):
                    context = browser.new_context()
                    page = context.new_page()
                    page.goto(url, wait_until="load")
                    paint, load = page.evaluate(PAINT)
                    paints.append(paint)
                    loads.append(load)
                    context.close()
                print(
                    f"{name}: first contentful paint {statistics.median(paints):.0f} ms, "
                    f"load {statistics.median(loads):.0f} ms (median of {args.visits} visits)"
                )
            browser.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
