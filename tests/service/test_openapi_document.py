"""The API's schema, pinned whole: a change to ``/openapi.json`` (a field, a route, a status, a
description) shows in review as a change to ``tests/service/openapi.json``, so that moving code
(splitting the schemas, renaming a module) is seen to change nothing a client reads. After a
change that is meant, write the file again with ``NANONAV_WRITE_OPENAPI=1 pytest
tests/service/test_openapi_document.py`` and review its diff."""

from __future__ import annotations

import json
import os
from pathlib import Path

from tests.conftest import Api

PINNED = Path(__file__).with_name("openapi.json")


def test_the_openapi_document_is_the_one_pinned(api: Api) -> None:
    document = api.client.get("/openapi.json").json()
    text = json.dumps(document, indent=1, sort_keys=True, ensure_ascii=False) + "\n"
    if os.environ.get("NANONAV_WRITE_OPENAPI") == "1":
        PINNED.write_text(text, encoding="utf-8")
    assert text == PINNED.read_text(encoding="utf-8"), (
        "/openapi.json changed: if meant, write tests/service/openapi.json again "
        "(NANONAV_WRITE_OPENAPI=1) and review its diff"
    )
