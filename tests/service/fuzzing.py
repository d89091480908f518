"""What the contract fuzz of the API shares over SQLite (tests/service/test_fuzz.py) and
PostgreSQL (tests/service/test_fuzz_postgres.py): a keyed API over a database that holds that
key's succeeded jobs (one evaluated a per-robot policy whose values are at the bound a policy may
hold, so its table views average the largest values there are), the policy and a study, so that
ids such as 1 and 2 reach the routes' real work; the settings of schemathesis, and the rules a
request the schema allows may still break."""

from __future__ import annotations

import threading
from typing import Any

import numpy as np
import schemathesis
from schemathesis.specs.openapi.checks import positive_data_acceptance

from nanonav.engine import qlearning
from nanonav.policy import MAX_Q
from nanonav.settings import Settings
from nanonav.store import JobStatus, JobStore, StudyJob, StudyStore, policy_name
from nanonav.store.migrate import upgrade
from service.app import create_app
from service.security import owner_of
from tests.service.test_security import KEY_A, bearer
from worker.job import run_job

# Rules a request the schema allows may still break, each stated in its operation's description
# and answered with a 422 whose every error carries the rule's type: they relate one value to
# another (epsilon_end to epsilon_start, an obstacle's radius to the cube), to the server's
# settings (the work budget, the hosts a callback may reach), to what is stored (the job a
# policy_from names, the size of a job's trajectory or cube) or to the engine (the labels and
# shape of a policy's table), which JSON Schema cannot say. Every route that stores what it is
# sent has the rules of its Idempotency-Key, and refuses U+0000 in any of its text, which
# PostgreSQL cannot keep (service.text).
WRITE_RULES = frozenset({"idempotency_key", "idempotency_key_reused", "nul_character"})
STATED_RULES: dict[str, frozenset[str]] = {
    "POST /jobs": frozenset(
        {
            "scenario_rule",
            "budget_exceeded",
            "policy_unusable",
            "refused",
            "quota_never_fits",
            *WRITE_RULES,
        }
    ),
    "POST /studies": frozenset(
        {
            "study_rule",
            "budget_exceeded",
            "policy_unusable",
            "refused",
            "too_many_jobs",
            "quota_never_fits",
        }
        | WRITE_RULES
    ),
    "POST /policies": frozenset(
        {"policy_layout", "policy_table", "policy_kind", "policy_model", "base64_decode"}
    )
    | WRITE_RULES,
    "GET /jobs/{job_id}/trajectory": frozenset({"too_large"}),
    "GET /jobs/{job_id}/heatmap.png": frozenset({"out_of_range"}),
}
# What schemathesis's own check takes from valid data besides 2xx and 3xx: a missing resource
# or credentials, a conflict with the state, a limit on rate.
ACCEPTED = {401, 403, 404, 409, 429}


def _extreme_policy(store: JobStore, owner: str, robots: int) -> str:
    """A per-robot policy of values at the bound, of both signs: their mean over the robots is
    what overflowed before the bound."""
    states, actions = qlearning.labels("behaviors")
    values = np.full((robots, len(states), len(actions)), MAX_Q)
    values[:, :, 1::2] = -MAX_Q
    record = store.policies.add(
        action_set="behaviors", communication=("none",), states=states, actions=actions,
        values=values, name="at the bound", owner=owner,
    )  # fmt: skip
    return policy_name(record.id)


def seeded_settings(url: str) -> Settings:
    """The settings of a keyed API over ``url``, migrated and seeded: job 1 evaluated policy 1
    (per robot, at the bound), job 2 learned a table; study 1."""
    upgrade(url)
    settings = Settings(database_url=url, api_keys=KEY_A)
    owner = owner_of(KEY_A)
    store = JobStore.from_url(url)
    evaluated: dict[str, Any] = {
        "robots": {"count": 2},
        "learning": {"episodes": 0, "max_steps": 30, "shared_table": False},
    }
    evaluated["policy_from"] = _extreme_policy(store, owner, robots=2)
    for scenario in (evaluated, {"learning": {"episodes": 1, "max_steps": 30}}):
        store.enqueue(scenario, robot_steps=1, episodes=2, owner=owner)
        claim = store.claim("fuzz", lease_s=30)
        assert claim is not None
        record = run_job(store, claim, settings, threading.Event())
        assert record is not None and record.status is JobStatus.SUCCEEDED, record
    StudyStore(store.engine).create(
        name="fuzz",
        spec={"grid": {"robots.count": [1, 2]}, "seeds": [0], "base": {}, "name": "fuzz"},
        jobs=[StudyJob({"robots": {"count": n}}, 1, 1, point, 0) for point, n in ((0, 1), (1, 2))],
        owner=owner,
    )
    store.close()
    return settings


CONFIG = schemathesis.Config.from_dict(
    {
        "seed": 20261201,
        # every request carries the key (the check that a request without one is refused runs
        # as schemathesis's own ignored_auth)
        "auth": {"openapi": {"HTTPBearer": {"bearer": KEY_A}}},
        # the first picture a process draws loads matplotlib, slow on a busy machine
        "request-timeout": 60,
        # the same requests every run: no examples replayed from earlier runs' database
        "generation": {"mode": "all", "max-examples": 25, "database": "none"},
        # a body over the size limit is refused too, with 413 (documented on every POST)
        "checks": {
            "negative_data_rejection": {
                "expected-statuses": [400, 401, 403, 404, 405, 406, 409, 413, 415, 422, 428, 429]
            }
        },
        "phases": {
            "examples": {"enabled": True},
            "coverage": {"enabled": True},
            "fuzzing": {"enabled": True},
            # each operation is tested alone here; sequences of calls (the stateful phase) are not
            "stateful": {"enabled": False},
        },
    }
)


def schema_of(url: str) -> schemathesis.BaseSchema:
    """The OpenAPI document of a keyed API over ``url`` (seeded first), every request sent with
    the key. An event stream of an unfinished job or study never ends by design, so the event
    routes are left out; tests/service/test_event_streams.py pins their 404 and 422 answers.
    Deletes run in tests/service/test_fuzz_deletes.py, so that the job and study every route
    here reads stay."""
    app = create_app(seeded_settings(url))
    schema = schemathesis.openapi.from_asgi(
        "/openapi.json", app, config=CONFIG, headers=bearer(KEY_A)
    )
    return schema.exclude(tag="events").exclude(method="DELETE")


def stated_rules_only(
    ctx: Any, response: schemathesis.Response, case: schemathesis.Case[Any]
) -> None:
    """``positive_data_acceptance``, but a valid request may be refused by a stated rule."""
    assert case.meta is not None
    if not case.meta.generation.mode.is_positive or response.status_code < 400:
        return
    if response.status_code in ACCEPTED or response.status_code >= 500:
        return  # a 5xx is not_a_server_error's to report
    rules = STATED_RULES[case.operation.label]
    errors = response.json().get("errors") if response.status_code == 422 else None
    broken = {error["type"] for error in errors or ()}
    assert errors and broken <= rules, (
        f"{case.operation.label} refused a request its schema allows with "
        f"{response.status_code}, not for a stated rule ({', '.join(sorted(rules))}) "
        f"[{case.meta.phase.name.value}: {case.meta.phase.data}]: "
        f"{response.text[:500]}"
    )


def keeps_the_contract(case: schemathesis.Case[Any]) -> None:
    """Send ``case`` and run every check on the answer."""
    if case.operation.label in STATED_RULES:
        case.call_and_validate(
            excluded_checks=[positive_data_acceptance], additional_checks=[stated_rules_only]
        )
    else:
        case.call_and_validate()
