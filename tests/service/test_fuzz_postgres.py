"""The contract of tests/service/test_fuzz.py, kept over PostgreSQL: its checks, its settings and
its seeded rows, in a schema of the test server's own. Ids up to MAX_EXACT_INT, the largest the
document allows, reach PostgreSQL's typed columns here, where they once failed a query that
SQLite answered."""

from __future__ import annotations

import atexit
from contextlib import ExitStack
from typing import Any

import pytest
import schemathesis
from hypothesis import HealthCheck, settings

from tests.conftest import postgres_schema
from tests.service.fuzzing import keeps_the_contract, schema_of

# Schemathesis reads the schema when the module is collected, so the database is made then, and
# dropped when the process ends.
_SCHEMAS = ExitStack()
atexit.register(_SCHEMAS.close)
try:
    schema = schema_of(_SCHEMAS.enter_context(postgres_schema()))
except pytest.skip.Exception as unreachable:
    # outside CI only, where no PostgreSQL answers (in CI postgres_schema fails instead): a
    # skip raised while collecting must be a module's, with the reason it gave
    pytest.skip(str(unreachable), allow_module_level=True)
# As tests/service/test_fuzz.py: each operation takes well under this on two busy cores.
pytestmark = pytest.mark.timeout(120)


@schema.parametrize()
@settings(deadline=None, suppress_health_check=list(HealthCheck))
def test_every_answer_keeps_the_openapi_contract_on_postgresql(
    case: schemathesis.Case[Any],
) -> None:
    keeps_the_contract(case)
