"""One poller per API process watches the jobs and studies that its event streams show.

A stream registers a :class:`Listener` for one id on a :class:`Channel` (one channel per kind of
thing: jobs, studies). While any listener is registered, the :class:`Poller` reads, every
``interval_s``, the state of every watched id of each channel with ONE store query per channel
(in a thread, off the event loop), and offers each listener that state; a listener takes it only
if it differs from the last state it was given. A listener holds only the latest state it has
not handed on, so a slow client costs one state of memory, never a queue that grows.

States are :class:`Snapshot`: encoded once per tick, shared by every listener of the id.
:class:`StreamLimits` bounds how many streams are open, per caller and in the process.
"""

from __future__ import annotations

import asyncio
import contextlib
import hashlib
import logging
from collections.abc import Callable, Collection, Iterator, Mapping
from dataclasses import dataclass

from fastapi.concurrency import run_in_threadpool
from sqlalchemy.exc import SQLAlchemyError

from service.problems import ProblemError

logger = logging.getLogger(__name__)
# How long a client refused a stream is asked to wait, seconds: places free as streams end.
STREAMS_RETRY_AFTER_S = 5


@dataclass(frozen=True)
class Snapshot:
    """One state of a job or a study, ready to send."""

    event_id: str  # "<status>-<digest of data>": names the state, so a client can resume
    status: str
    data: str  # the JSON document an event carries
    finished: bool  # the last state the thing will have

    @classmethod
    def of(cls, status: str, data: str, *, finished: bool) -> Snapshot:
        digest = hashlib.blake2b(data.encode(), digest_size=8).hexdigest()
        return cls(f"{status}-{digest}", status, data, finished)


Read = Callable[[Collection[int]], Mapping[int, Snapshot]]


class Listener:
    """One client's watch on one id: the latest state it has not yet been handed."""

    def __init__(self, seen: str | None) -> None:
        self.seen = seen  # event id of the last state the client was given or already had
        self._latest: Snapshot | None = None
        self._ready = asyncio.Event()
        self._closed = False

    def offer(self, snapshot: Snapshot) -> None:
        """Keep ``snapshot`` if it is new to this client, replacing any not yet handed on."""
        if snapshot.event_id == self.seen:
            return
        self.seen = snapshot.event_id
        self._latest = snapshot
        self._ready.set()

    def close(self) -> None:
        """No state will come any more (the poller stopped, or the thing was deleted)."""
        self._closed = True
        self._ready.set()

    async def next(self) -> Snapshot | None:
        """The next new state, waiting for it; None once the poller has stopped."""
        while self._latest is None:
            if self._closed:
                return None
            self._ready.clear()
            await self._ready.wait()
        latest, self._latest = self._latest, None
        return latest


class Channel:
    """The listeners of one kind of thing, and how to read the state of many of them at once."""

    def __init__(self, read: Read, poller: Poller) -> None:
        self.read = read
        self._poller = poller
        self._listeners: dict[int, set[Listener]] = {}
        self._count = 0  # kept apart so that another thread may read it while streams come and go

    @contextlib.contextmanager
    def listen(self, thing_id: int, seen: str | None) -> Iterator[Listener]:
        """A listener for ``thing_id`` while the block runs; ``seen`` is the event id of the
        state the client already has."""
        if not self._poller.running:
            raise RuntimeError("the event poller is not running (the app's lifespan starts it)")
        listener = Listener(seen)
        self._listeners.setdefault(thing_id, set()).add(listener)
        self._count += 1
        self._poller.wake()
        try:
            yield listener
        finally:
            self._count -= 1
            watchers = self._listeners.get(thing_id, set())
            watchers.discard(listener)
            if not watchers:
                self._listeners.pop(thing_id, None)

    @property
    def listeners(self) -> int:
        return self._count

    @property
    def running(self) -> bool:
        return self._poller.running

    def watched(self) -> dict[int, list[Listener]]:
        """Who watches what, now: a tick offers its states only to those who were listening
        before it read them, so no one is offered a state older than the one they started from."""
        return {thing_id: list(watchers) for thing_id, watchers in self._listeners.items()}

    def close(self) -> None:
        for watchers in self._listeners.values():
            for listener in watchers:
                listener.close()


class Poller:
    """Reads the watched ids of every channel every ``interval_s`` while anyone listens."""

    def __init__(self, interval_s: float) -> None:
        self.interval_s = interval_s
        self.ticks = 0
        self._channels: list[Channel] = []
        self._wake = asyncio.Event()
        self._stop = asyncio.Event()
        self._task: asyncio.Task[None] | None = None

    def channel(self, read: Read) -> Channel:
        channel = Channel(read, self)
        self._channels.append(channel)
        return channel

    @property
    def running(self) -> bool:
        return self._task is not None and not self._task.done() and not self._stop.is_set()

    def start(self) -> None:
        self._task = asyncio.get_running_loop().create_task(self._run(), name="event-poller")

    async def stop(self) -> None:
        """Stop polling and end every open stream (each ends after the state it has sent)."""
        self._stop.set()
        self._wake.set()
        if self._task is not None:
            await self._task

    def wake(self) -> None:
        self._wake.set()

    async def _run(self) -> None:
        loop = asyncio.get_running_loop()
        try:
            while not self._stop.is_set():
                if not any(channel.listeners for channel in self._channels):
                    self._wake.clear()
                    await self._wake.wait()
                    continue
                started = loop.time()
                await self.tick()
                await self._sleep(started + self.interval_s - loop.time())
        except Exception:
            logger.exception("the event poller failed: every event stream ends")
            raise
        finally:
            self._stop.set()
            for channel in self._channels:
                channel.close()

    async def tick(self) -> None:
        """One read per channel with listeners, then each state to each of its listeners."""
        watched = [(channel, channel.watched()) for channel in self._channels if channel.listeners]
        self.ticks += 1
        try:
            states = await run_in_threadpool(
                lambda: [channel.read(list(ids)) for channel, ids in watched]
            )
        except SQLAlchemyError as error:
            # The database may be busy or restarting: the streams wait for the next tick.
            logger.warning("the event poller could not read the store: %s", error)
            return
        for (_, listeners), found in zip(watched, states, strict=True):
            for thing_id, watchers in listeners.items():
                snapshot = found.get(thing_id)
                for listener in watchers:
                    if snapshot is None:  # deleted: its streams end; reconnecting gets 404
                        listener.close()
                    else:
                        listener.offer(snapshot)

    async def _sleep(self, seconds: float) -> None:
        if seconds <= 0:
            return
        with contextlib.suppress(TimeoutError):
            async with asyncio.timeout(seconds):
                await self._stop.wait()


class TooManyStreams(ProblemError):
    """No place for another event stream: the caller's, or the process's, are all taken."""

    status = 503
    slug = "too-many-streams"
    title = "Too many event streams"
    headers = {"Retry-After": str(STREAMS_RETRY_AFTER_S)}  # noqa: RUF012  (read-only)


class StreamLimits:
    """The event streams open in this process, per caller and in all. Each holds a connection,
    two tasks and a listener until its job or study ends: 2,000 of them kept every other
    request waiting a second or more, and one client could open them all."""

    def __init__(self, per_key: int, per_process: int) -> None:
        self.per_key = per_key
        self.per_process = per_process
        self._open: dict[str, int] = {}
        self._total = 0

    @property
    def open(self) -> int:
        return self._total

    @contextlib.contextmanager
    def hold(self, key: str) -> Iterator[None]:
        """A place for one stream of ``key`` (a key's owner, or a client address) while the
        block runs; :class:`TooManyStreams` if there is none."""
        if self._total >= self.per_process:
            raise TooManyStreams(
                f"this server has {self._total} event streams open, the most it keeps "
                "(NANONAV_EVENTS_STREAMS_PER_PROCESS); try again shortly, or poll GET /jobs/{id}"
            )
        held = self._open.get(key, 0)
        if held >= self.per_key:
            raise TooManyStreams(
                f"{held} event streams are open for this key (without keys, this address), "
                "the most one may have (NANONAV_EVENTS_STREAMS_PER_KEY); close one, or poll "
                "GET /jobs/{id}"
            )
        self._open[key] = held + 1
        self._total += 1
        try:
            yield
        finally:
            self._total -= 1
            left = self._open[key] - 1
            if left:
                self._open[key] = left
            else:
                del self._open[key]
