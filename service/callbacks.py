"""A submit's ``callback_url``: refused with 422 unless this server may call it; kept (by the
store, see ``add_waiting``) in the form the sender will send it, which /callback answers."""

from __future__ import annotations

from typing import Annotated

from fastapi import Query

from nanonav.settings import Settings
from nanonav.store.deliveries import DeliveryRecord
from nanonav.webhooks import MAX_URL_LENGTH, Refused, callback_target
from service.problems import InvalidInput, field_error
from service.schemas import Callback

CallbackUrl = Annotated[
    str | None,
    Query(
        max_length=MAX_URL_LENGTH,
        description="Where to POST a signed JSON summary when it ends (a host the server's "
        "NANONAV_WEBHOOK_HOSTS permits); stored and answered in the form it is sent to.",
    ),
]


def check_callback(url: str | None, settings: Settings) -> str | None:
    """``url`` as the sender will send it, or ``InvalidInput`` naming ``callback_url`` if the
    server will not call it."""
    if url is None:
        return None
    try:
        return str(callback_target(url, settings.webhook_hosts))
    except Refused as why:
        detail = f"callback_url {url!r} is refused: {why}"
        raise InvalidInput(
            detail, [field_error(["query", "callback_url"], detail, "refused")]
        ) from None


def callback_answer(record: DeliveryRecord) -> Callback:
    return Callback.model_validate(record, from_attributes=True)
