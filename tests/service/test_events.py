"""The poller behind the event streams, with a store stand-in that counts its reads."""

from __future__ import annotations

import asyncio
import contextlib
import logging
from collections.abc import Callable, Collection, Coroutine, Mapping
from typing import Any

import pytest
from sqlalchemy.exc import OperationalError

from service.events import Listener, Poller, Snapshot

INTERVAL_S = 0.02


class Things:
    """States by id, and every read made of them."""

    def __init__(self) -> None:
        self.states: dict[int, Snapshot] = {}
        self.reads: list[list[int]] = []
        self.fail = False

    def set(self, thing_id: int, status: str, n: int, *, finished: bool = False) -> Snapshot:
        self.states[thing_id] = Snapshot.of(status, f'{{"n": {n}}}', finished=finished)
        return self.states[thing_id]

    def read(self, ids: Collection[int]) -> Mapping[int, Snapshot]:
        self.reads.append(sorted(ids))
        if self.fail:
            raise OperationalError("SELECT", {}, Exception("database is locked"))
        return {i: self.states[i] for i in ids if i in self.states}


def run(coroutine: Coroutine[Any, Any, None]) -> None:
    asyncio.run(asyncio.wait_for(coroutine, timeout=10))


async def next_state(listener: Listener) -> Snapshot | None:
    return await asyncio.wait_for(listener.next(), timeout=2)


async def until(holds: Callable[[], bool], timeout_s: float = 3.0) -> None:
    """Wait, a tick at a time, until ``holds()`` (the poller's thread may be slow to get the
    processor while the whole suite shares two cores); fail after ``timeout_s``."""
    deadline = asyncio.get_running_loop().time() + timeout_s
    while not holds():
        assert asyncio.get_running_loop().time() < deadline, "it never held"
        await asyncio.sleep(INTERVAL_S)


def test_a_snapshot_is_named_by_its_status_and_a_digest_of_its_data() -> None:
    one = Snapshot.of("running", '{"n": 1}', finished=False)
    assert one.event_id.startswith("running-") and len(one.event_id) == len("running-") + 16
    assert one == Snapshot.of("running", '{"n": 1}', finished=False)
    assert one.event_id != Snapshot.of("running", '{"n": 2}', finished=False).event_id


def test_one_read_per_tick_serves_every_listener_of_every_id() -> None:
    async def scenario() -> None:
        things = Things()
        for i in range(3):
            things.set(i, "running", 0)
        poller = Poller(INTERVAL_S)
        channel = poller.channel(things.read)
        poller.start()
        with contextlib.ExitStack() as stack:
            listeners = [stack.enter_context(channel.listen(i % 3, None)) for i in range(100)]
            assert channel.listeners == 100
            firsts = await asyncio.gather(*(next_state(ln) for ln in listeners))
            assert firsts == [things.states[i % 3] for i in range(100)]
            ticks = poller.ticks
            await until(lambda: poller.ticks - ticks >= 5)
            # one read per tick however many listen (give or take the tick under way)
            assert abs(len(things.reads) - poller.ticks) <= 1
            assert all(ids == [0, 1, 2] for ids in things.reads)
        assert channel.listeners == 0
        await poller.stop()

    run(scenario())


def test_nothing_is_read_while_no_one_listens() -> None:
    async def scenario() -> None:
        things = Things()
        things.set(1, "queued", 0)
        poller = Poller(INTERVAL_S)
        channel = poller.channel(things.read)
        poller.start()
        await asyncio.sleep(5 * INTERVAL_S)
        assert things.reads == []
        with channel.listen(1, None) as listener:
            assert await next_state(listener) == things.states[1]
        reads = len(things.reads)
        await asyncio.sleep(5 * INTERVAL_S)
        assert len(things.reads) <= reads + 1  # at most a tick that had already begun
        await poller.stop()

    run(scenario())


def test_a_listener_gets_only_states_new_to_it() -> None:
    async def scenario() -> None:
        things = Things()
        had = things.set(1, "queued", 0)
        poller = Poller(INTERVAL_S)
        channel = poller.channel(things.read)
        poller.start()
        with channel.listen(1, had.event_id) as listener:
            await until(lambda: len(things.reads) >= 2)  # it was read, and again
            with pytest.raises(TimeoutError):
                await asyncio.wait_for(listener.next(), timeout=3 * INTERVAL_S)
            changed = things.set(1, "running", 1)
            assert await next_state(listener) == changed
        await poller.stop()

    run(scenario())


def test_a_slow_listener_keeps_only_the_latest_state() -> None:
    async def scenario() -> None:
        listener = Listener(seen=None)
        states = [Snapshot.of("running", f'{{"n": {n}}}', finished=False) for n in range(1000)]
        for state in states:
            listener.offer(state)
        assert await next_state(listener) == states[-1]
        with pytest.raises(TimeoutError):
            await asyncio.wait_for(listener.next(), timeout=0.05)

    run(scenario())


def test_stopping_the_poller_ends_every_listener_and_refuses_new_ones() -> None:
    async def scenario() -> None:
        things = Things()
        things.set(1, "running", 0)
        poller = Poller(INTERVAL_S)
        channel = poller.channel(things.read)
        poller.start()
        with channel.listen(1, things.states[1].event_id) as listener:
            waiting = asyncio.ensure_future(listener.next())
            await asyncio.sleep(2 * INTERVAL_S)
            await poller.stop()
            assert await asyncio.wait_for(waiting, timeout=1) is None
        with pytest.raises(RuntimeError, match="not running"), channel.listen(1, None):
            pass

    run(scenario())


def test_a_listener_of_a_thing_deleted_under_it_is_ended_and_the_others_go_on() -> None:
    async def scenario() -> None:
        things = Things()
        things.set(1, "running", 0)
        things.set(2, "running", 0)
        poller = Poller(INTERVAL_S)
        channel = poller.channel(things.read)
        poller.start()
        with channel.listen(1, None) as gone, channel.listen(2, None) as kept:
            assert await next_state(gone) == things.states[1]
            assert await next_state(kept) == things.states[2]
            del things.states[1]
            assert await next_state(gone) is None
            finished = things.set(2, "succeeded", 1, finished=True)
            assert await next_state(kept) == finished
        await poller.stop()

    run(scenario())


def test_a_failed_read_is_logged_and_the_next_tick_tries_again(
    caplog: pytest.LogCaptureFixture,
) -> None:
    async def scenario() -> None:
        things = Things()
        things.fail = True
        poller = Poller(INTERVAL_S)
        channel = poller.channel(things.read)
        poller.start()
        with channel.listen(1, None) as listener:
            await until(lambda: len(things.reads) >= 2)  # it failed, and tried again
            things.fail = False
            things.set(1, "running", 5)
            assert await next_state(listener) == things.states[1]
        await poller.stop()

    with caplog.at_level(logging.WARNING, logger="service.events"):
        run(scenario())
    assert "database is locked" in caplog.text
