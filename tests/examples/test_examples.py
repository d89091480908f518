"""The tutorials' scripts in ``examples/`` run as written against a real API and worker, each
tutorial page shows its script as it is, and the ``curl`` and ``nanonav`` commands of the README
and the tutorials run as printed (on a fresh service, where the ids they name are the first)."""

from __future__ import annotations

import json
import re
import shlex
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import httpx
import pytest

from nanonav.store import JobStatus, JobStore
from tests.conftest import LiveApi, api_and_worker
from tests.processes import clean_environment, free_port

pytestmark = pytest.mark.timeout(300)

ROOT = Path(__file__).resolve().parents[2]
EXAMPLES = ROOT / "examples"
README = ROOT / "README.md"
TUTORIALS = {
    "first_job.py": ROOT / "docs/tutorials/first-job.md",
    "first_study.py": ROOT / "docs/tutorials/first-study.md",
    "train_and_evaluate.py": ROOT / "docs/tutorials/train-and-evaluate.md",
}
# The pages whose shell commands are run here, each on a service of its own.
COMMAND_PAGES = [README, TUTORIALS["first_job.py"], TUTORIALS["first_study.py"]]
PNG = b"\x89PNG\r\n\x1a\n"


def run_example(name: str, url: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, str(EXAMPLES / name)],
        cwd=cwd,
        env=clean_environment(NANONAV_URL=url),
        capture_output=True,
        text=True,
        timeout=240,
    )


def found(pattern: str, text: str) -> int:
    match = re.search(pattern, text)
    assert match is not None, f"{pattern!r} not in:\n{text}"
    return int(match.group(1))


def fenced(text: str, language: str) -> list[str]:
    """The contents of a page's code blocks fenced as ``language``."""
    return re.findall(rf"^```{language}\n(.*?)^```$", text, flags=re.DOTALL | re.MULTILINE)


# ---------------------------------------------------------------- the scripts


def test_first_job_prints_the_jobs_table_1_and_saves_its_pictures(
    live_api: LiveApi, tmp_path: Path
) -> None:
    done = run_example("first_job.py", live_api.url, tmp_path)
    assert done.returncode == 0, done.stderr
    job_id = found(r"job (\d+) succeeded", done.stdout)
    store = JobStore.from_url(live_api.database_url)
    try:
        record = store.get(job_id)
    finally:
        store.close()
    assert record.status is JobStatus.SUCCEEDED
    assert record.scenario["seed"] == 7 and record.scenario["learning"]["episodes"] == 20
    summary = httpx.get(f"{live_api.url}/jobs/{job_id}/metrics").json()["summary"]
    assert f"success_rate: {summary['success_rate']:.3f}" in done.stdout
    assert f"total_steps: {summary['total_steps']:.3f}" in done.stdout
    for name in ("trajectory", "learning"):
        assert (tmp_path / "first-job" / f"{name}.png").read_bytes().startswith(PNG)


def test_first_study_prints_each_policys_interval_and_the_paired_difference(
    live_api: LiveApi, tmp_path: Path
) -> None:
    done = run_example("first_study.py", live_api.url, tmp_path)
    assert done.returncode == 0, done.stderr
    study_id = found(r"study (\d+) succeeded", done.stdout)
    study = httpx.get(f"{live_api.url}/studies/{study_id}").json()
    assert study["jobs"]["succeeded"] == study["jobs"]["total"] == 10
    by_policy = {point["values"]["robots.policy"]: point for point in study["points"]}
    steps = by_policy["q_learning"]["metrics"]["total_steps"]
    assert f"q_learning   total_steps: {steps['mean']:.3f} [{steps['ci_low']:.3f}," in done.stdout
    [comparison] = study["comparisons"]
    difference = comparison["metrics"]["total_steps"]["mean_difference"]
    assert f"q_learning - gradient total_steps: {difference:+.3f}" in done.stdout
    rows = (tmp_path / "first-study" / "results.csv").read_text().splitlines()
    assert len(rows) == 1 + 10
    assert (tmp_path / "first-study" / "total_steps.png").read_bytes().startswith(PNG)


def test_train_and_evaluate_sends_its_table_and_evaluates_it_beside_the_baselines(
    live_api: LiveApi, tmp_path: Path
) -> None:
    done = run_example("train_and_evaluate.py", live_api.url, tmp_path)
    assert done.returncode == 0, done.stderr
    policy_id = found(r"policy (\d+): policy_from", done.stdout)
    policy = httpx.get(f"{live_api.url}/policies/{policy_id}").json()
    assert sum(abs(v) for row in policy["values"] for v in row) > 0, "it learned nothing"
    jobs = {
        name: found(rf"(?m)^\s+{name}\s+(\d+)\s", done.stdout)
        for name in ("learned", "gradient", "rule")
    }
    scenarios = {name: httpx.get(f"{live_api.url}/jobs/{i}").json() for name, i in jobs.items()}
    assert all(job["status"] == "succeeded" for job in scenarios.values())
    learned = scenarios["learned"]["scenario"]
    assert learned["policy_from"] == f"policy-{policy_id}"
    assert learned["learning"]["episodes"] == 0
    assert {job["scenario"]["seed"] for job in scenarios.values()} == {7}
    assert scenarios["rule"]["scenario"]["robots"]["policy"] == "rule"


@pytest.mark.parametrize("name", sorted(TUTORIALS))
def test_a_script_without_a_service_says_so_at_once_and_does_no_work(
    name: str, tmp_path: Path
) -> None:
    url = f"http://127.0.0.1:{free_port()}"
    started = time.monotonic()
    done = run_example(name, url, tmp_path)
    assert done.returncode == 1
    assert f"cannot reach the NanoNav API at {url}" in done.stderr
    assert "make run" in done.stderr and "NANONAV_URL" in done.stderr
    assert done.stdout == "", "it started work before it knew the service was there"
    assert time.monotonic() - started < 60
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("name", sorted(TUTORIALS))
def test_each_tutorial_shows_its_script_as_it_is(name: str) -> None:
    script = (EXAMPLES / name).read_text()
    assert script in fenced(TUTORIALS[name].read_text(), "python"), (
        f"{TUTORIALS[name].name} must show examples/{name} as it is"
    )


# ---------------------------------------------------------------- the README


def readme_snippet() -> str:
    [snippet] = [code for code in fenced(README.read_text(), "python") if "Client()" in code]
    return snippet


def test_the_readmes_client_snippet_is_first_jobs_and_runs(live_api: LiveApi) -> None:
    snippet = readme_snippet()
    example = {line.strip() for line in (EXAMPLES / "first_job.py").read_text().splitlines()}
    shared = [line.strip() for line in snippet.splitlines() if "api." in line or "=" in line]
    assert [line for line in shared if line not in example and "print" not in line] == []
    done = subprocess.run(
        [sys.executable, "-c", snippet],
        env=clean_environment(NANONAV_URL=live_api.url),
        capture_output=True,
        text=True,
        timeout=240,
    )
    assert done.returncode == 0, done.stderr
    status, success_rate, total_steps = done.stdout.split()
    assert status == "succeeded" and 0 <= float(success_rate) <= 1 and float(total_steps) > 0


def test_the_readme_stays_a_front_door() -> None:
    lines = README.read_text().splitlines()
    assert len(lines) <= 300
    first_screen = "\n".join(lines[:45])
    assert "make run" in first_screen and "docs/" in first_screen
    assert "docs/reference/scenario.md" in first_screen, "where the reference lives"
    assert "curl -s -X POST localhost:8000/jobs" in first_screen


# ---------------------------------------------------------------- the pages' commands


def commands(page: Path) -> list[str]:
    """The page's ``curl`` and ``nanonav`` commands, in order, continued lines joined."""
    found = []
    for block in fenced(page.read_text(), "sh"):
        for line in block.replace("\\\n", " ").splitlines():
            if line.split()[:1] in (["curl"], ["nanonav"]):
                found.append(line)
    return found


def shell_words(command: str) -> list[str]:
    """The command without its comment, as the shell splits it."""
    lexer = shlex.shlex(command, posix=True, punctuation_chars=False)
    lexer.whitespace_split = True
    lexer.commenters = "#"
    return list(lexer)


def idle(url: str) -> None:
    """Until nothing is queued or running: the commands after a submit read its results."""
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline:
        jobs = httpx.get(f"{url}/jobs", params={"limit": 100}).json()["jobs"]
        if jobs and all(job["status"] not in ("queued", "running") for job in jobs):
            return
        time.sleep(0.1)
    raise AssertionError("the jobs did not finish")


def refused(output: str) -> bool:
    """Whether ``output`` is a problem document (a 4xx or 5xx answer that curl -s prints)."""
    try:
        body = json.loads(output)
    except ValueError:
        return False
    return isinstance(body, dict) and isinstance(body.get("status"), int) and "title" in body


@pytest.fixture(params=COMMAND_PAGES, ids=lambda page: page.name)
def page(request: pytest.FixtureRequest) -> Path:
    path: Path = request.param
    return path


@pytest.fixture
def fresh_service(tmp_path: Path) -> Iterator[str]:
    """An API and a worker over a new database: the first job submitted is job 1."""
    with api_and_worker(tmp_path / "service") as (api, _, _):
        yield api.url


def test_every_command_a_page_shows_runs_as_printed(
    page: Path, fresh_service: str, tmp_path: Path
) -> None:
    shown = commands(page)
    assert shown, f"{page.name} shows no command"
    port = fresh_service.rsplit(":", 1)[1]
    nanonav = str(Path(sys.executable).with_name("nanonav"))
    env = clean_environment(NANONAV_URL=fresh_service)
    work = tmp_path / "work"
    work.mkdir()
    for command in shown:
        words = shell_words(command.replace("localhost:8000", f"localhost:{port}"))
        writes = words[0] == "nanonav" and words[1] in ("submit", "study")
        if "-X" not in words and not writes:
            idle(fresh_service)
        if words[0] == "nanonav":
            words[0] = nanonav
        done = subprocess.run(words, cwd=work, env=env, capture_output=True, text=True, timeout=180)
        assert done.returncode == 0, f"{command}\n{done.stdout}\n{done.stderr}"
        assert not refused(done.stdout), f"{command}\n{done.stdout}"
        if "-so" in words:
            written = work / words[words.index("-so") + 1]
            assert written.stat().st_size > 0, command
            if written.suffix == ".png":
                assert written.read_bytes().startswith(PNG), command
    if page in (README, TUTORIALS["first_job.py"]):
        the_same_job_twice(fresh_service)


def the_same_job_twice(url: str) -> None:
    """The page's curl and its ``nanonav submit`` made the same job (jobs 1 and 2): the same
    scenario, and so the same numbers (the page says so; the CLI ran 50 training episodes
    where curl asked for 20)."""
    idle(url)
    first, second = (httpx.get(f"{url}/jobs/{job}").json() for job in (1, 2))
    assert first["scenario"] == second["scenario"]
    assert first["scenario"]["learning"]["episodes"] == 20
    summaries = [httpx.get(f"{url}/jobs/{job}/metrics").json()["summary"] for job in (1, 2)]
    first_numbers, second_numbers = (
        {k: v for k, v in summary.items() if k != "duration_s"} for summary in summaries
    )  # everything but the wall-clock time each took
    assert first_numbers == second_numbers and "total_steps" in first_numbers
