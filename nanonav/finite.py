"""JSON has no NaN and no infinity: a document is made finite before it is stored or sent, each
such number written as null (as pydantic writes them). The worker does so to the metrics it
stores; the API to the answers it builds itself, as a backstop (``service.responses``)."""

from __future__ import annotations

import math
from typing import Any


def finite(document: Any, found: list[str] | None = None, pointer: str = "#") -> Any:
    """``document`` with every NaN and infinity as None; ``found``, when given, gets where each
    was, as a JSON pointer in a URI fragment (RFC 6901: ``#/values/0/1``)."""
    if isinstance(document, float):
        if math.isfinite(document):
            return document
        if found is not None:
            found.append(pointer)
        return None
    if isinstance(document, dict):
        return {k: finite(v, found, f"{pointer}/{_token(k)}") for k, v in document.items()}
    if isinstance(document, list | tuple):
        return [finite(v, found, f"{pointer}/{i}") for i, v in enumerate(document)]
    return document


def _token(key: Any) -> str:
    return str(key).replace("~", "~0").replace("/", "~1")
