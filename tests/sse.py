"""Reading a text/event-stream as a browser's EventSource does, for the event-stream tests."""

from __future__ import annotations

import json
from collections.abc import AsyncIterator, Iterable, Iterator
from dataclasses import dataclass
from typing import Any

import httpx


@dataclass
class Message:
    """One block of the stream up to a blank line: an event, a bare ``retry:``, or a comment."""

    event: str | None = None
    data: str | None = None
    id: str | None = None
    retry: int | None = None
    comment: str | None = None

    def json(self) -> Any:
        assert self.data is not None, self
        return json.loads(self.data)


class _Parser:
    def __init__(self) -> None:
        self.block = Message()

    def feed(self, line: str) -> Message | None:
        """The block a blank line ends, if it held anything."""
        if line == "":
            done, self.block = self.block, Message()
            return None if done == Message() else done
        name, _, value = line.partition(":")
        value = value.removeprefix(" ")
        if name == "":
            self.block.comment = value
        elif name == "data":
            self.block.data = value if self.block.data is None else f"{self.block.data}\n{value}"
        elif name == "event":
            self.block.event = value
        elif name == "id":
            self.block.id = value
        elif name == "retry":
            self.block.retry = int(value)
        return None


def messages(lines: Iterable[str]) -> Iterator[Message]:
    parser = _Parser()
    for line in lines:
        found = parser.feed(line)
        if found is not None:
            yield found


async def amessages(response: httpx.Response) -> AsyncIterator[Message]:
    parser = _Parser()
    async for line in response.aiter_lines():
        found = parser.feed(line)
        if found is not None:
            yield found


def events(response: httpx.Response) -> Iterator[Message]:
    """The events with data, in order; keep-alive comments and bare ``retry:`` left out."""
    return (m for m in messages(response.iter_lines()) if m.data is not None)
