"""The one place that reads the environment: a typed, validated ``Settings`` object.

Every variable has the ``NANONAV_`` prefix; ``DATABASE_URL``, ``HOST`` and ``PORT`` are also read
without it, as platforms and ``make run`` set them. Values are checked when the object is built,
so a bad configuration stops a process at start-up, not at its first request.
"""

from __future__ import annotations

import re
from functools import lru_cache
from ipaddress import IPv4Network, IPv6Network, ip_network
from typing import Annotated

from pydantic import AliasChoices, Field, SecretStr, field_validator, model_validator
from pydantic_settings import BaseSettings, NoDecode, SettingsConfigDict
from sqlalchemy.engine import make_url
from sqlalchemy.exc import ArgumentError

DEFAULT_DATABASE_URL = "sqlite:///var/nanonav.db"
DEFAULT_API_URL = "http://127.0.0.1:8000"
MIN_WEBHOOK_SECRET_LENGTH = 32
SECRET_RECIPE = "python -c 'import secrets; print(secrets.token_urlsafe(32))'"
API_KEY_CHARACTERS = re.compile(r"[A-Za-z0-9._~+/=-]+")
# Words that mark a secret copied from an example rather than made for the deployment.
PLACEHOLDER_WORDS = ("changeme", "changethis", "change-me", "password", "secret", "example",
                     "placeholder", "xxxxxxxx")  # fmt: skip


def _aliases(name: str, *unprefixed: str) -> AliasChoices:
    return AliasChoices(f"NANONAV_{name.upper()}", *unprefixed, name)


class Settings(BaseSettings):
    """Configuration of the API, the worker and the store."""

    model_config = SettingsConfigDict(
        env_prefix="NANONAV_",
        extra="ignore",
        frozen=True,
        hide_input_in_errors=True,  # a refused secret must not reach a log
        validate_by_name=True,
    )

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
        2_000_000,
        ge=1024,
        description="Largest request body the API reads, bytes; larger ones get 413. A "
        "recurrent network sent as a policy takes about 1.6 MB in base64.",
    )
    robot_steps_budget: int = Field(
        1_000_000_000,
        ge=1,
        description="Largest robots x max_steps x (training episodes + evaluation worlds) a "
        "submitted scenario may cost.",
    )
    work_budget: int = Field(
        500_000_000_000,
        ge=1,
        description="Largest Scenario.work a submitted scenario may cost: robot-steps weighed by "
        "the field sources, obstacles and cells each one goes through, in units of about a "
        "nanosecond of one core (5e11: about ten minutes at most on one core).",
    )
    job_time_limit_s: float = Field(
        3600.0,
        gt=0,
        description="Wall-clock seconds a job may run before it is stopped and failed.",
    )
    progress_interval_s: float = Field(
        0.25,
        gt=0,
        description="Least time between two progress writes of a running job; each write also "
        "renews the lease and reads whether a cancel was requested.",
    )
    poll_interval_s: float = Field(
        0.2,
        gt=0,
        description="How long an idle worker waits between two looks at the queue; on "
        "PostgreSQL a job queued meanwhile wakes it at once (LISTEN/NOTIFY).",
    )
    lease_s: float = Field(
        15.0,
        gt=0,
        description="How long a claim holds without being renewed: a running worker renews it "
        "from a thread every third of it; a job whose lease ran out (its worker died) is "
        "queued again by the next sweep (every 3 s), so within about lease_s + 5 s.",
    )
    store_busy_timeout_s: float = Field(
        30.0,
        gt=0,
        le=3600,
        description="How long a write waits for another's lock before it fails (SQLite's busy "
        "timeout, PostgreSQL's lock_timeout); a worker then retries it with backoff, and the "
        "job goes on.",
    )
    max_attempts: int = Field(
        3,
        ge=1,
        description="Claims a job may get before an expired lease fails it instead.",
    )
    worker_nice: int = Field(
        5,
        ge=0,
        le=19,
        description="Niceness a worker process adds to itself, so that on a shared machine the "
        "API answers promptly while simulations run; 0 leaves the priority alone.",
    )
    api_processes: int = Field(
        1,
        ge=1,
        le=64,
        description="API processes `nanonav api` serves with (uvicorn's workers) unless "
        "--processes says otherwise; all share the store, so any one may answer any request.",
    )
    worker_concurrency: int = Field(
        1,
        ge=1,
        le=256,
        description="Worker processes `nanonav worker` starts unless --concurrency says otherwise.",
    )
    worker_trains: bool = Field(
        False,
        description="Workers also claim the jobs that train a network (robots.policy ppo or "
        "recurrent_ppo), as `nanonav worker --train` does; they need the rl extra (torch). "
        "Without it a worker never claims one.",
    )
    training_device: str = Field(
        "auto",
        pattern=r"^(auto|cpu|cuda(:[0-9]{1,2})?)$",
        description="Where a worker that trains learns: 'auto' (a GPU where torch sees one, "
        "else the CPU), 'cpu', 'cuda' or 'cuda:N'. The worlds are stepped on the CPU.",
    )
    training_threads: int = Field(
        1,
        ge=1,
        le=256,
        description="Torch threads of a worker that trains (its collector takes one more "
        "core): one, because on a shared machine two collapsed to a fraction of one's speed.",
    )

    retention_days: float | None = Field(
        None,
        gt=0,
        le=36_500,
        allow_inf_nan=False,
        description="Days a finished job (of no study) or an ended study is kept after it "
        "ended; workers then delete it with its results, in batches, about once a minute. "
        "Unset: everything is kept until deleted with DELETE /jobs/{id} or /studies/{id}.",
    )

    study_max_jobs: int = Field(
        2000,
        ge=1,
        description="Most jobs one study may make (grid points x seeds); larger ones get 422.",
    )
    drawing_queue: int = Field(
        32,
        ge=1,
        le=10_000,
        description="Pictures an API process may have waiting to be drawn (it draws one at a "
        "time, the first time each is asked for); a request beyond them gets 503.",
    )

    events_poll_s: float = Field(
        0.25,
        gt=0,
        le=60,
        description="How often an API process reads the state of the jobs and studies its open "
        "event streams watch (one query for all watched jobs, one for all watched studies), "
        "seconds; nothing is read while no stream is open.",
    )

    shutdown_grace_s: int = Field(
        5,
        ge=1,
        le=3600,
        description="Seconds a stopping API process gives open requests to finish before it "
        "cancels them. An event stream lasts until its job or study finishes, so without this "
        "limit the server would wait for every watching client to leave.",
    )

    # --- Slow clients and open streams: what one API process holds for clients it cannot
    # hurry (service/connections.py, service/events.py). ---
    api_max_connections: int = Field(
        1000,
        ge=1,
        le=100_000,
        description="Connections one API process serves at once (default 1000). Past them a "
        "new connection takes the place of the one idle longest (waiting for a request head "
        "for a second or more); with none idle, a request on it gets 503 with Retry-After. With "
        "api_healthz_connections and 128 files of its own they must fit the open-file limit "
        "(RLIMIT_NOFILE): the soft limit is raised to fit if the hard one allows, else the "
        "API refuses to start.",
    )
    api_healthz_connections: int = Field(
        16,
        ge=1,
        le=1000,
        description="Connections past api_max_connections, all busy, on which an API process "
        "answers /healthz alone (default 16), once each, and 503 to anything else; a "
        "connection past them is closed at once.",
    )
    api_header_timeout_s: float = Field(
        10.0,
        gt=0,
        le=3600,
        description="Seconds a client has to send a whole request head (default 10), from "
        "when it connected or sent the first byte of its next request; then it gets 408 and "
        "the connection is closed (one that sent nothing is closed without a word).",
    )
    api_body_timeout_s: float = Field(
        30.0,
        gt=0,
        le=3600,
        description="Seconds a client has to send a whole request body after its head "
        "(default 30; a 1 MB body at 35 kB/s); then it gets 408, if nothing was answered yet, "
        "and the connection is closed.",
    )
    events_streams_per_key: int = Field(
        50,
        ge=1,
        le=100_000,
        description="Event streams one key (without keys: one client address) may have open "
        "on one API process (default 50); another gets 503 with Retry-After.",
    )
    events_streams_per_process: int = Field(
        500,
        ge=1,
        le=100_000,
        description="Event streams one API process keeps open (default 500), so that other "
        "requests still get connections and time; another gets 503 with Retry-After.",
    )
    # --- end of slow clients and open streams ---

    trajectory_json_values: int = Field(
        2_000_000,
        ge=1000,
        description="Most numbers a trajectory answered as JSON may hold (about 20 bytes each); "
        "a larger one is refused with 422 that says to use ?stride= or ?format=npz.",
    )

    webhook_hosts: Annotated[tuple[str, ...], NoDecode] = Field(
        (),
        description="Comma-separated hosts a job's or study's callback_url may name: "
        "'hooks.example.org' exactly, '*.example.org' its subdomains, 'localhost:9000' only "
        "that port. Empty: no webhooks, and a callback_url gets 422.",
    )
    webhook_addresses: Annotated[tuple[IPv4Network | IPv6Network, ...], NoDecode] = Field(
        (),
        description="Comma-separated addresses and networks ('127.0.0.0/8,10.1.2.3,fd00::/8') "
        "webhooks may go to besides public ones. A callback's host is resolved when it is sent, "
        "and a loopback, private, link-local, unspecified, multicast, reserved or shared address "
        "is refused unless listed here; a cloud metadata address (169.254.169.254, "
        "fd00:ec2::254, ...) only if listed alone. Empty: public addresses only.",
    )
    webhook_secret: SecretStr | None = Field(
        None,
        validation_alias="NANONAV_WEBHOOK_SECRET",
        description="The key webhooks are signed with (HMAC-SHA256, the NanoNav-Signature "
        f"header); needed with webhook_hosts, at least {MIN_WEBHOOK_SECRET_LENGTH} characters "
        "and no placeholder.",
    )
    webhook_timeout_s: float = Field(
        10.0,
        gt=0,
        le=300,
        description="How long a webhook's receiver has to answer before the try counts as failed.",
    )
    webhook_attempts: int = Field(
        12,
        ge=1,
        le=100,
        description="Tries a webhook gets before it is given up (its state says so).",
    )
    webhook_retry_s: float = Field(
        10.0,
        gt=0,
        le=3600,
        description="Wait before a failed webhook's second try; it doubles after each failure, "
        "up to an hour (12 tries span about 3.6 hours).",
    )
    idempotency_ttl_s: float = Field(
        86400.0,
        ge=1,
        le=30 * 86400,
        description="How long an Idempotency-Key names its first request: within it the same "
        "request gets the same job, study or policy back and another request is refused; after "
        "it the key is free for a new one.",
    )

    api_keys: Annotated[tuple[SecretStr, ...], NoDecode] = Field(
        (),
        description="Comma-separated keys a client must send as 'Authorization: Bearer <key>' "
        f"on every route but /healthz, each at least {MIN_WEBHOOK_SECRET_LENGTH} characters and "
        "no placeholder; jobs and studies then belong to the key that made them. Empty (the "
        "default): no keys, every job is everyone's.",
    )
    session_secret: SecretStr | None = Field(
        None,
        description="The key the dashboard's session tokens are signed with (HMAC-SHA256), at "
        f"least {MIN_WEBHOOK_SECRET_LENGTH} characters and no placeholder; rotating it logs "
        "every browser out. Unset: derived from the API keys, so every API process agrees and "
        "changing any key logs every browser out.",
    )
    session_ttl_s: float = Field(
        8 * 3600.0,
        ge=60,
        le=30 * 86400,
        description="How long a dashboard login lasts, seconds: its token is refused after it, "
        "and the person logs in again.",
    )
    quota_active_jobs: int = Field(
        2000,
        ge=0,
        description="Most queued and running jobs one key (or, without keys, one client "
        "address) may have, by default as many as the largest study makes; a submit past it "
        "gets 429, one that alone is larger gets 422. 0: no limit.",
    )
    quota_robot_steps: int = Field(
        10_000_000_000,
        ge=0,
        description="Most robot-steps (the budget's measure) one key or client address may have "
        "queued and running, by default ten full-budget jobs; a submit past it gets 429, one "
        "that alone is larger gets 422. 0: no limit.",
    )
    policy_model_max_bytes: int = Field(
        1_400_000,
        ge=1024,
        description="Largest ONNX model a policy may be, bytes (POST /policies sends it in "
        "base64, a third larger, within max_body_bytes). A network of two hidden layers of 64 "
        "takes about 25 kB, sb3-contrib's recurrent PPO (an LSTM of 256) 1.2 MB.",
    )
    network_memory_bytes: int = Field(
        1_073_741_824,
        ge=268_435_456,
        description="Address space of the process a network sent as a policy is checked and "
        "run in, bytes (RLIMIT_AS); past it the network fails, not the API or the worker. The "
        "process takes about 0.3 GB with ONNX Runtime loaded, and a call at most a quarter of "
        "a gigabyte more (a policy's counted cost).",
    )
    network_check_cpu_s: float = Field(
        20.0,
        ge=2,
        le=3600,
        description="CPU seconds the check of a network sent to POST /policies may take in its "
        "process, its start included (about 1 s); past it the network is refused with 422.",
    )
    network_call_limit_s: float = Field(
        30.0,
        gt=0,
        le=3600,
        description="Wall-clock seconds one call of a network may take while a job evaluates "
        "it (a call's counted cost keeps it under a second on one core); past it the job "
        "fails, saying so.",
    )
    network_checks_at_once: int = Field(
        2,
        ge=1,
        le=64,
        description="Networks an API process checks at once, each in a process of its own; "
        "up to network_checks_waiting more wait (without holding a thread), and one that has "
        "waited 30 s is answered 503 with Retry-After.",
    )
    network_checks_waiting: int = Field(
        8,
        ge=0,
        le=256,
        description="POST /policies requests an API process takes in while its checks are "
        "busy, besides those being checked; past them a request is answered 503 checks-busy "
        "with Retry-After at once, before its body is read. With network_checks_at_once they "
        "bound what uploads hold of the API's memory: each at most a few times max_body_bytes.",
    )
    quota_policies: int = Field(
        1000,
        ge=0,
        description="Most policies (POST /policies) one key may keep, or without keys the "
        "whole server; one more gets 409 until one is deleted. Each is at most max_body_bytes "
        "as sent. 0: no limit.",
    )
    allowed_hosts: Annotated[tuple[str, ...], NoDecode] = Field(
        ("localhost", "127.0.0.1", "::1"),
        description="Comma-separated Host names the API answers ('*.example.org' for "
        "subdomains, '*' for any, '::1' or '[::1]' for an IPv6 address); another gets 400, "
        "against DNS rebinding. A deployment sets its own name.",
    )
    allowed_origins: Annotated[tuple[str, ...], NoDecode] = Field(
        (),
        description="Comma-separated origins ('https://lab.example.org') other than the API's "
        "own from which a browser may send a POST or DELETE; any other Origin gets 403.",
    )

    @field_validator("api_keys", "allowed_hosts", "allowed_origins", mode="before")
    @classmethod
    def _split_list(cls, value: object) -> object:
        if isinstance(value, str):
            return tuple(part.strip() for part in value.split(",") if part.strip())
        return value

    @field_validator("allowed_hosts")
    @classmethod
    def _allowed_host_patterns(cls, hosts: tuple[str, ...]) -> tuple[str, ...]:
        for host in hosts:
            if "*" in host and host != "*" and not (host.startswith("*.") and "*" not in host[1:]):
                raise ValueError(f"{host!r}: '*' stands alone, or as '*.' before a domain")
        return hosts

    @field_validator("api_keys")
    @classmethod
    def _real_keys(cls, keys: tuple[SecretStr, ...]) -> tuple[SecretStr, ...]:
        for key in keys:
            value = key.get_secret_value()
            _check_secret(value, "an API key")
            if not API_KEY_CHARACTERS.fullmatch(value):
                raise ValueError(
                    "an API key may hold only letters, digits and - _ . ~ + / = (it travels in "
                    f"a header and a cookie); make one with {SECRET_RECIPE}"
                )
        return keys

    @field_validator("allowed_origins")
    @classmethod
    def _origins(cls, origins: tuple[str, ...]) -> tuple[str, ...]:
        for origin in origins:
            scheme, sep, rest = origin.partition("://")
            if scheme not in {"http", "https"} or not sep or not rest or "/" in rest:
                raise ValueError(f"an origin looks like 'https://lab.example.org', not {origin!r}")
        return tuple(origin.lower().rstrip("/") for origin in origins)

    @field_validator("webhook_hosts", mode="before")
    @classmethod
    def _split_hosts(cls, value: object) -> object:
        if isinstance(value, str):
            return tuple(part.strip() for part in value.split(",") if part.strip())
        return value

    @field_validator("webhook_hosts")
    @classmethod
    def _host_patterns(cls, hosts: tuple[str, ...]) -> tuple[str, ...]:
        for host in hosts:
            name, colon, port = host.partition(":")
            wild = name.startswith("*.")
            if not name or "*" in (name[2:] if wild else name) or "/" in host:
                raise ValueError(f"a webhook host looks like 'hooks.example.org', "
                                 f"'*.example.org' or 'localhost:9000', not {host!r}")  # fmt: skip
            if colon and not (port.isascii() and port.isdigit() and 0 < int(port) < 65536):
                raise ValueError(f"not a port in webhook host {host!r}")
        return tuple(host.lower() for host in hosts)

    @field_validator("webhook_addresses", mode="before")
    @classmethod
    def _networks(cls, value: object) -> object:
        if isinstance(value, str):
            value = tuple(part.strip() for part in value.split(",") if part.strip())
        if not isinstance(value, list | tuple):
            return value
        return tuple(_network(entry) for entry in value)

    @field_validator("webhook_secret")
    @classmethod
    def _real_secret(cls, secret: SecretStr | None) -> SecretStr | None:
        if secret is not None:
            _check_secret(secret.get_secret_value(), "the webhook secret")
        return secret

    @field_validator("session_secret")
    @classmethod
    def _real_session_secret(cls, secret: SecretStr | None) -> SecretStr | None:
        if secret is not None:
            _check_secret(secret.get_secret_value(), "the session secret")
        return secret

    @model_validator(mode="after")
    def _webhooks_are_signed(self) -> Settings:
        if self.webhook_hosts and self.webhook_secret is None:
            raise ValueError(
                "NANONAV_WEBHOOK_HOSTS is set but NANONAV_WEBHOOK_SECRET is not: webhooks are "
                f"always signed; make a secret with {SECRET_RECIPE}"
            )
        return self

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
        try:
            url.get_dialect().import_dbapi()
        except ImportError as error:
            raise ValueError(
                f"a {url.get_backend_name()} database needs the {url.get_driver_name()} driver, "
                f"which is not installed ({error}): install NanoNav's 'postgres' extra, "
                "pip install -e '.[postgres]' (make run does when DATABASE_URL is postgresql://)"
            ) from None
        return url.render_as_string(hide_password=False)


def _network(entry: object) -> object:
    """A webhook address or network as written (``10.1.2.3``, ``127.0.0.0/8``), checked."""
    if not isinstance(entry, str):
        return entry
    try:
        return ip_network(entry)
    except ValueError as error:
        if "has host bits set" in str(error):
            meant = ip_network(entry, strict=False)
            raise ValueError(f"in NANONAV_WEBHOOK_ADDRESSES, {entry!r} has host bits set: "
                             f"did you mean {meant}?") from None  # fmt: skip
        raise ValueError(f"in NANONAV_WEBHOOK_ADDRESSES, {entry!r} is not an address or a "
                         "network (like 10.1.2.3, 127.0.0.0/8 or fd00::/8)") from None  # fmt: skip


def _check_secret(value: str, what: str) -> None:
    """Refuse a secret too short to resist guessing, or copied from an example."""
    if len(value) < MIN_WEBHOOK_SECRET_LENGTH:
        raise ValueError(
            f"{what} is shorter than {MIN_WEBHOOK_SECRET_LENGTH} characters; "
            f"make one with {SECRET_RECIPE}"
        )
    if any(word in value.lower() for word in PLACEHOLDER_WORDS) or len(set(value)) < 8:
        raise ValueError(f"{what} looks like a placeholder; make one with {SECRET_RECIPE}")


class ClientSettings(BaseSettings):
    """Configuration of the HTTP client and the commands that talk to a running API; apart
    from ``Settings`` so that a client never needs (or validates) the server's database."""

    model_config = SettingsConfigDict(env_prefix="NANONAV_", extra="ignore", frozen=True)

    url: str = Field(
        DEFAULT_API_URL,
        description="Base URL of the NanoNav API that `nanonav submit`, `study`, `fetch`, "
        "`jobs` and `nanonav.client.Client` talk to.",
    )
    api_key: SecretStr | None = Field(
        None,
        description="The key sent as 'Authorization: Bearer <key>' to an API that has "
        "NANONAV_API_KEYS set; never printed.",
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
