"""The API keeps the contract its OpenAPI document states, for whatever a client sends: requests
generated from the document (its examples, the coverage of every keyword's edges, and fuzzing,
valid and invalid alike) against every route of an API with keys, sent with one, over a real
SQLite file seeded as tests/service/fuzzing.py says. Every check schemathesis has runs: no 5xx,
documented statuses, content types, headers and bodies, valid data accepted and invalid data
refused, 405 with a true ``Allow`` for methods a path does not take, and a key demanded wherever
the document says so. tests/service/test_fuzz_postgres.py runs the same over PostgreSQL."""

from __future__ import annotations

import tempfile
from pathlib import Path
from typing import Any

import pytest
import schemathesis
from hypothesis import HealthCheck, settings

from tests.service.fuzzing import keeps_the_contract, schema_of

# Schemathesis reads the schema when the module is collected, so the database is made then.
_DIRECTORY = tempfile.TemporaryDirectory(prefix="nanonav-fuzz-")
schema = schema_of(f"sqlite:///{Path(_DIRECTORY.name) / 'nanonav.db'}")
# Every operation's examples, coverage and fuzzing take well under this on two busy cores.
pytestmark = pytest.mark.timeout(120)


@schema.parametrize()
@settings(deadline=None, suppress_health_check=list(HealthCheck))
def test_every_answer_keeps_the_openapi_contract(case: schemathesis.Case[Any]) -> None:
    keeps_the_contract(case)
