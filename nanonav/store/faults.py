"""What a failed store call means for the job that made it, and what may be said of it.

A *transient* fault (the write lock held past the busy timeout, a connection dropped, a server
restarting) passes: the call is retried with backoff and the job goes on. A *permanent* one (a
value the database will never take, such as a result over its size limit) will fail the same
way every time: the job fails at once, with the reason. Neither kind is the simulation's fault,
and nothing said of either names SQL, parameters or lease tokens.
"""

from __future__ import annotations

from sqlalchemy.exc import (
    DataError,
    DBAPIError,
    DisconnectionError,
    InterfaceError,
    OperationalError,
    SQLAlchemyError,
)
from sqlalchemy.exc import TimeoutError as PoolTimeout

# Words in a driver's message that mean the value itself is refused, however often it is sent.
PERMANENT_WORDS = ("too big", "too large", "program limit", "exceeds the maximum",
                   "invalid memory alloc request", "out of memory")  # fmt: skip


def reason(error: BaseException) -> str:
    """The driver's own message, first line only: no statement, no parameters."""
    original = getattr(error, "orig", None) or error
    text = str(original).strip().splitlines()
    return text[0] if text else type(original).__name__


def is_permanent(error: BaseException) -> bool:
    """Whether sending the same thing again can only fail the same way."""
    if not isinstance(error, SQLAlchemyError):
        return False
    message = reason(error).lower()
    return isinstance(error, DataError) or any(word in message for word in PERMANENT_WORDS)


def is_transient(error: BaseException) -> bool:
    """Whether the same call may well succeed in a moment."""
    if is_permanent(error):
        return False
    if isinstance(error, DBAPIError) and error.connection_invalidated:
        return True
    return isinstance(error, OperationalError | DisconnectionError | InterfaceError | PoolTimeout)
