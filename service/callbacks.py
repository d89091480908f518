"""A submit's ``callback_url``: refused with 422 unless this server may call it."""

from __future__ import annotations

from typing import Annotated

from fastapi import Query

from nanonav.settings import Settings
from nanonav.store.deliveries import DeliveryRecord
from nanonav.webhooks import MAX_URL_LENGTH, refusal
from service.problems import InvalidInput, field_error
from service.schemas import Callback

CallbackUrl = Annotated[
    str | None,
    Query(
        max_length=MAX_URL_LENGTH,
        description="Where to POST a signed JSON summary when it ends (a host the server's "
        "NANONAV_WEBHOOK_HOSTS permits).",
    ),
]


def check_callback(url: str | None, settings: Settings) -> None:
    """``InvalidInput`` naming ``callback_url`` if the server will not call ``url``."""
    if url is None:
        return
    why = refusal(url, settings.webhook_hosts)
    if why is not None:
        detail = f"callback_url {url!r} is refused: {why}"
        raise InvalidInput(detail, [field_error(["query", "callback_url"], detail, "refused")])


def callback_answer(record: DeliveryRecord) -> Callback:
    return Callback.model_validate(record, from_attributes=True)
