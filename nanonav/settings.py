"""The one place that reads the environment: a typed, validated ``Settings`` object.

Every variable has the ``NANONAV_`` prefix; ``DATABASE_URL``, ``HOST`` and ``PORT`` are also read
without it, as platforms and ``make run`` set them. Values are checked when the object is built,
so a bad configuration stops a process at start-up, not at its first request.
"""

from __future__ import annotations

from functools import lru_cache

from pydantic import AliasChoices, Field, field_validator
from pydantic_settings import BaseSettings, SettingsConfigDict
from sqlalchemy.engine import make_url
from sqlalchemy.exc import ArgumentError

DEFAULT_DATABASE_URL = "sqlite:///var/nanonav.db"
DEFAULT_API_URL = "http://127.0.0.1:8000"


def _aliases(name: str, *unprefixed: str) -> AliasChoices:
    return AliasChoices(f"NANONAV_{name.upper()}", *unprefixed, name)


class Settings(BaseSettings):
    """Configuration of the API, the worker and the store."""

    model_config = SettingsConfigDict(env_prefix="NANONAV_", extra="ignore", frozen=True)

    database_url: str = Field(
        DEFAULT_DATABASE_URL,
        validation_alias=_aliases("database_url", "DATABASE_URL"),
        description="SQLAlchemy URL of the job store; a relative SQLite path is relative to the "
        "working directory. 'postgresql://' means the psycopg 3 driver.",
    )
    host: str = Field(
        "127.0.0.1", validation_alias=_aliases("host", "HOST"), description="API bind address."
    )
    port: int = Field(
        8000, ge=1, le=65535, validation_alias=_aliases("port", "PORT"), description="API port."
    )
    max_body_bytes: int = Field(
        1_000_000,
        ge=1024,
        validation_alias=_aliases("max_body_bytes"),
        description="Largest request body the API reads, bytes; larger ones get 413.",
    )
    robot_steps_budget: int = Field(
        1_000_000_000,
        ge=1,
        validation_alias=_aliases("robot_steps_budget"),
        description="Largest robots x max_steps x (training episodes + evaluation worlds) a "
        "submitted scenario may cost.",
    )
    work_budget: int = Field(
        500_000_000_000,
        ge=1,
        validation_alias=_aliases("work_budget"),
        description="Largest Scenario.work a submitted scenario may cost: robot-steps weighed by "
        "the field sources, obstacles and cells each one goes through, in units of about a "
        "nanosecond of one core (5e11: about ten minutes at most on one core).",
    )
    job_time_limit_s: float = Field(
        3600.0,
        gt=0,
        validation_alias=_aliases("job_time_limit_s"),
        description="Wall-clock seconds a job may run before it is stopped and failed.",
    )
    progress_interval_s: float = Field(
        0.25,
        gt=0,
        validation_alias=_aliases("progress_interval_s"),
        description="Least time between two progress writes of a running job; each write also "
        "renews the lease and reads whether a cancel was requested.",
    )
    poll_interval_s: float = Field(
        0.2,
        gt=0,
        validation_alias=_aliases("poll_interval_s"),
        description="How long an idle worker sleeps between two looks at the queue.",
    )
    lease_s: float = Field(
        15.0,
        gt=0,
        validation_alias=_aliases("lease_s"),
        description="How long a claim holds without being renewed: a running worker renews it "
        "from a thread every third of it; a job whose lease ran out (its worker died) is "
        "queued again by the next sweep (every 3 s), so within about lease_s + 5 s.",
    )
    store_busy_timeout_s: float = Field(
        30.0,
        gt=0,
        le=3600,
        validation_alias=_aliases("store_busy_timeout_s"),
        description="How long a SQLite write waits for another's lock before it fails; a "
        "worker then retries it with backoff, and the job goes on.",
    )
    max_attempts: int = Field(
        3,
        ge=1,
        validation_alias=_aliases("max_attempts"),
        description="Claims a job may get before an expired lease fails it instead.",
    )
    worker_nice: int = Field(
        5,
        ge=0,
        le=19,
        validation_alias=_aliases("worker_nice"),
        description="Niceness a worker process adds to itself, so that on a shared machine the "
        "API answers promptly while simulations run; 0 leaves the priority alone.",
    )
    worker_concurrency: int = Field(
        1,
        ge=1,
        le=256,
        validation_alias=_aliases("worker_concurrency"),
        description="Worker processes `nanonav worker` starts unless --concurrency says otherwise.",
    )

    study_max_jobs: int = Field(
        2000,
        ge=1,
        validation_alias=_aliases("study_max_jobs"),
        description="Most jobs one study may make (grid points x seeds); larger ones get 422.",
    )
    drawing_queue: int = Field(
        32,
        ge=1,
        le=10_000,
        validation_alias=_aliases("drawing_queue"),
        description="Pictures an API process may have waiting to be drawn (it draws one at a "
        "time, the first time each is asked for); a request beyond them gets 503.",
    )

    events_poll_s: float = Field(
        0.25,
        gt=0,
        le=60,
        validation_alias=_aliases("events_poll_s"),
        description="How often an API process reads the state of the jobs and studies its open "
        "event streams watch (one query for all watched jobs, one for all watched studies), "
        "seconds; nothing is read while no stream is open.",
    )

    shutdown_grace_s: int = Field(
        5,
        ge=1,
        le=3600,
        validation_alias=_aliases("shutdown_grace_s"),
        description="Seconds a stopping API process gives open requests to finish before it "
        "cancels them. An event stream lasts until its job or study finishes, so without this "
        "limit the server would wait for every watching client to leave.",
    )

    trajectory_json_values: int = Field(
        2_000_000,
        ge=1000,
        validation_alias=_aliases("trajectory_json_values"),
        description="Most numbers a trajectory answered as JSON may hold (about 20 bytes each); "
        "a larger one is refused with 422 that says to use ?stride= or ?format=npz.",
    )

    @field_validator("database_url")
    @classmethod
    def _known_url(cls, value: str) -> str:
        try:
            url = make_url(value)
        except ArgumentError as error:
            raise ValueError(f"not a database URL: {error}") from None
        if url.drivername in {"postgresql", "postgres"}:
            url = url.set(drivername="postgresql+psycopg")
        if url.get_backend_name() not in {"sqlite", "postgresql"}:
            raise ValueError("only sqlite:// and postgresql:// databases are supported")
        return url.render_as_string(hide_password=False)


class ClientSettings(BaseSettings):
    """Configuration of the HTTP client and the commands that talk to a running API; apart
    from ``Settings`` so that a client never needs (or validates) the server's database."""

    model_config = SettingsConfigDict(env_prefix="NANONAV_", extra="ignore", frozen=True)

    url: str = Field(
        DEFAULT_API_URL,
        validation_alias=_aliases("url"),
        description="Base URL of the NanoNav API that `nanonav submit`, `study`, `fetch`, "
        "`jobs` and `nanonav.client.Client` talk to.",
    )

    @field_validator("url")
    @classmethod
    def _http_url(cls, value: str) -> str:
        if not value.startswith(("http://", "https://")):
            raise ValueError(f"not an http:// or https:// URL: {value!r}")
        return value.rstrip("/")


@lru_cache(maxsize=1)
def get_settings() -> Settings:
    """The process's settings, read from the environment once."""
    return Settings()
