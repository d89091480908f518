"""Fixtures shared by the store, service, worker and end-to-end tests: real databases only.

SQLite is a file under ``tmp_path``. PostgreSQL is the local server (``NANONAV_TEST_POSTGRES_URL``,
by default postgres@127.0.0.1:5432/test), one fresh schema per test; it is skipped when it does not
answer, except in CI (``CI`` set to true, 1 or yes), where that is a failure.
"""

from __future__ import annotations

import os
import shutil
import signal
import socket
import tempfile
import threading
import time
import uuid
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import httpx
import pytest
import uvicorn
from sqlalchemy import create_engine, text
from sqlalchemy.engine import make_url
from sqlalchemy.exc import OperationalError
from starlette.types import ASGIApp

from nanonav.client import tls_context
from nanonav.settings import Settings
from nanonav.store import JobStore
from nanonav.store.migrate import upgrade
from service.app import create_app
from service.server import server_config
from tests.compile_ahead import compile_all
from tests.processes import ApiServer, Worker

# What a script sends so that a body-less POST (a cancel) is not taken for a cross-site form.
SCRIPTED = {"X-Requested-With": "nanonav-tests"}
# In-process test clients (httpx's ASGI transport, schemathesis) send ``Host: testserver``.
os.environ.setdefault("NANONAV_ALLOWED_HOSTS", "localhost,127.0.0.1,testserver")

POSTGRES_URL = os.environ.get(
    "NANONAV_TEST_POSTGRES_URL", "postgresql+psycopg://postgres@127.0.0.1:5432/test"
)


def pytest_configure(config: pytest.Config) -> None:
    """A suite started in the background (``make test &``) inherits Ctrl-C ignored, and so would
    every process it starts: the tests that press Ctrl-C need it to reach them. A suite spread
    over test processes (``-n 2``) first compiles the engine's kernels once, side by side
    (``tests.compile_ahead``), rather than in every test process."""
    if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
        signal.signal(signal.SIGINT, signal.default_int_handler)
    spread = (config.getoption("numprocesses", None) or 0) > 0
    if spread and not hasattr(config, "workerinput"):
        report = config.pluginmanager.get_plugin("terminalreporter")
        for line in compile_all():
            if report is not None:
                report.write_line(f"compiled ahead: {line}")


# The suite's slow kinds, marked by the folder they live in: real processes end to end, a real
# browser, and the benchmarks' smoke runs. ``make test-fast`` leaves them out; ``make test``
# (and CI) runs everything.
FOLDER_MARKS = {"e2e": "e2e", "browser": "browser", "benchmarks": "benchmark"}


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """Each test under ``tests/e2e``, ``tests/browser`` or ``tests/benchmarks`` gets its
    folder's mark (``FOLDER_MARKS``), so that ``-m "not e2e"`` and the like choose by kind."""
    root = Path(__file__).resolve().parent
    for item in items:
        parts = Path(str(item.path)).resolve().relative_to(root).parts
        mark = FOLDER_MARKS.get(parts[0]) if len(parts) > 1 else None
        if mark is not None:
            item.add_marker(mark)


def in_ci() -> bool:
    """Whether this is CI, where what could run must: a missing service fails, not skips."""
    return os.environ.get("CI", "").lower() in {"1", "true", "yes"}


def sqlite_url_in(directory: Path) -> str:
    return f"sqlite:///{directory / 'nanonav.db'}"


@pytest.fixture
def sqlite_url(tmp_path: Path) -> str:
    return sqlite_url_in(tmp_path)


@contextmanager
def postgres_schema() -> Iterator[str]:
    """A URL of the test server whose connections work in a fresh schema, dropped afterwards."""
    schema = f"test_{uuid.uuid4().hex[:12]}"
    admin = create_engine(POSTGRES_URL, isolation_level="AUTOCOMMIT")
    try:
        with admin.connect() as connection:
            connection.execute(text(f'CREATE SCHEMA "{schema}"'))
    except OperationalError as error:
        admin.dispose()
        if in_ci():
            pytest.fail(f"PostgreSQL must answer in CI: {error}")
        pytest.skip(f"PostgreSQL is not reachable: {error}")
    url = make_url(POSTGRES_URL).update_query_dict({"options": f"-csearch_path={schema}"})
    try:
        yield url.render_as_string(hide_password=False)
    finally:
        with admin.connect() as connection:
            connection.execute(text(f'DROP SCHEMA "{schema}" CASCADE'))
        admin.dispose()


@pytest.fixture
def postgres_url() -> Iterator[str]:
    with postgres_schema() as url:
        yield url


@pytest.fixture(params=["sqlite", "postgresql"])
def database_url(request: pytest.FixtureRequest) -> str:
    """Each store test runs on a SQLite file and on PostgreSQL."""
    name = "sqlite_url" if request.param == "sqlite" else "postgres_url"
    return str(request.getfixturevalue(name))


_MIGRATED: list[tempfile.TemporaryDirectory[str]] = []  # removed when the process ends


def migrate(url: str) -> None:
    """``upgrade`` ``url`` to the newest migration; a SQLite file that does not exist yet is a
    copy of one this test process migrated once (alembic took 0.1 s a test;
    tests/store/test_migrations.py runs the migrations themselves)."""
    parsed = make_url(url)
    target = Path(parsed.database or "")
    if parsed.get_backend_name() != "sqlite" or not parsed.database or target.exists():
        upgrade(url)
        return
    if not _MIGRATED:
        _MIGRATED.append(tempfile.TemporaryDirectory(prefix="nanonav-migrated-"))
        upgrade(sqlite_url_in(Path(_MIGRATED[0].name)))
    target.parent.mkdir(parents=True, exist_ok=True)  # as upgrade makes a file's folder
    shutil.copyfile(Path(_MIGRATED[0].name) / "nanonav.db", target)


@contextmanager
def migrated_store(url: str) -> Iterator[JobStore]:
    """A store on ``url`` with the schema at the newest migration, closed afterwards."""
    migrate(url)
    job_store = JobStore.from_url(url)
    try:
        yield job_store
    finally:
        job_store.close()


@pytest.fixture
def store(database_url: str) -> Iterator[JobStore]:
    with migrated_store(database_url) as job_store:
        yield job_store


@pytest.fixture
def sqlite_store(sqlite_url: str) -> Iterator[JobStore]:
    with migrated_store(sqlite_url) as job_store:
        yield job_store


@contextmanager
def serve(app: ASGIApp) -> Iterator[str]:
    """Serve ``app`` with a real uvicorn on a free local port, configured as the API always is
    (``service.server``) under the app's own settings; yields its base URL."""
    sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    sock.bind(("127.0.0.1", 0))
    port = sock.getsockname()[1]
    settings = getattr(getattr(app, "state", None), "settings", None)
    if not isinstance(settings, Settings):
        settings = Settings()
    config = server_config(
        app, settings, log_level="warning", lifespan="on", timeout_graceful_shutdown=2
    )
    server = uvicorn.Server(config)
    thread = threading.Thread(target=server.run, kwargs={"sockets": [sock]}, daemon=True)
    thread.start()
    # bounded, to catch a server that never starts, and long enough for a machine whose two
    # cores are both compiling (one start took over 10 s so in a fresh clone's run)
    deadline = time.monotonic() + 30
    while not server.started:
        if time.monotonic() > deadline or not thread.is_alive():
            raise RuntimeError("the test server did not start")
        time.sleep(0.01)
    try:
        yield f"http://127.0.0.1:{port}"
    finally:
        server.should_exit = True
        thread.join(timeout=10)
        sock.close()


@dataclass
class Api:
    """A running API over a migrated SQLite file, and a client for it."""

    url: str
    client: httpx.Client
    database_url: str
    store: JobStore


@pytest.fixture
def api_settings(sqlite_url: str) -> Settings:
    return Settings(database_url=sqlite_url, max_body_bytes=64 * 1024)


@pytest.fixture
def api(api_settings: Settings) -> Iterator[Api]:
    migrate(api_settings.database_url)
    store = JobStore.from_url(api_settings.database_url)
    with (
        serve(create_app(api_settings)) as url,
        httpx.Client(base_url=url, timeout=30, headers=SCRIPTED, verify=tls_context()) as client,
    ):
        yield Api(url=url, client=client, database_url=api_settings.database_url, store=store)
    store.close()


@dataclass
class LiveApi:
    """An API process and a worker process over one SQLite file, as a user runs them."""

    url: str
    database_url: str


@contextmanager
def api_and_worker(directory: Path, **api_env: str) -> Iterator[tuple[ApiServer, Worker, str]]:
    """An API process and a worker process over a migrated SQLite file in ``directory``, both
    ready; yields both and the database URL, and stops both afterwards."""
    url = sqlite_url_in(directory)
    migrate(url)
    api = ApiServer(url, directory / "api.log", cwd=None, **api_env)  # api_env: variables only
    worker = Worker(url, directory / "worker.log")
    try:
        api.wait_ready()
        worker.wait_ready()
        yield api, worker, url
    finally:
        api.terminate()
        worker.terminate()


@contextmanager
def api_with_worker(directory: Path, **api_env: str) -> Iterator[tuple[ApiServer, str]]:
    """``api_and_worker``'s API and database URL."""
    with api_and_worker(directory, **api_env) as (api, _, url):
        yield api, url


@pytest.fixture(scope="session")
def live_api(tmp_path_factory: pytest.TempPathFactory) -> Iterator[LiveApi]:
    """Started once per test session, with the worker's engine loaded, so the client and
    command tests that share it run their jobs in milliseconds."""
    with api_with_worker(tmp_path_factory.mktemp("live")) as (api, url):
        yield LiveApi(url=api.url, database_url=url)
