"""The ``Idempotency-Key`` header: checked, read as UTF-8, and tied to the request it came with.

The digest is of the body as JSON means it (keys sorted, spacing ignored) and of the
``callback_url``, not of the scenario it resolves to: ``{}`` resolves to a fresh random seed each
time, and sending it again must still be the same request.
"""

from __future__ import annotations

import hashlib
import json
from typing import Annotated

from fastapi import Depends, Header, Request

from nanonav.store import Idempotency
from service.deps import SettingsDep
from service.problems import InvalidInput, field_error

KEY_MAX_CHARS = 200
LOC = ("header", "idempotency-key")


def _refuse(detail: str) -> InvalidInput:
    return InvalidInput(detail, [field_error(LOC, detail, "idempotency_key")])


def _decoded(raw: str) -> str:
    """HTTP headers arrive as latin-1; clients send UTF-8 in them, so read the bytes as that."""
    try:
        return raw.encode("latin-1").decode("utf-8")
    except UnicodeError:
        raise _refuse("the Idempotency-Key header is not valid UTF-8") from None


def _canonical(body: bytes) -> bytes:
    try:
        parsed = json.loads(body)
    except ValueError:
        return body  # the route refuses it anyway; the digest needs only to be stable
    return json.dumps(parsed, sort_keys=True, separators=(",", ":")).encode()


async def _idempotency(
    request: Request,
    settings: SettingsDep,
    idempotency_key: Annotated[
        str | None,
        Header(
            max_length=4 * KEY_MAX_CHARS,
            description=f"Makes retries safe: the same key with the same request gives the same "
            f"job, study or policy back for `NANONAV_IDEMPOTENCY_TTL_S` (a day by default); the "
            f"same key with another request is refused with 422. UTF-8, 1 to {KEY_MAX_CHARS} "
            f"characters, not blank.",
        ),
    ] = None,
) -> Idempotency | None:
    if idempotency_key is None:
        return None
    key = _decoded(idempotency_key)
    if not key.strip():
        raise _refuse("the Idempotency-Key header is empty; leave it out or send a key")
    if len(key) > KEY_MAX_CHARS:
        detail = f"the Idempotency-Key has {len(key)} characters, more than {KEY_MAX_CHARS}"
        raise _refuse(detail)
    digest = hashlib.sha256(_canonical(await request.body()))
    digest.update(b"\0" + request.query_params.get("callback_url", "").encode())
    return Idempotency(key=key, digest=digest.hexdigest(), ttl_s=settings.idempotency_ttl_s)


IdempotencyDep = Annotated[Idempotency | None, Depends(_idempotency)]
