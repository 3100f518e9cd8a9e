"""The relay's frame slot keeps only the newest value: slow readers skip, nothing queues."""

from __future__ import annotations

import asyncio

import pytest

from telemetry.domain.newest import Closed, Newest


async def test_a_reader_gets_the_newest_value_and_skips_the_ones_between():
    slot: Newest[str] = Newest()
    for value in ("a", "b", "c"):
        slot.put(value)
    assert await slot.newer(0) == (3, "c")


async def test_a_reader_waits_for_a_value_newer_than_its_own():
    slot: Newest[int] = Newest()
    slot.put(1)
    waiting = asyncio.create_task(slot.newer(1))
    await asyncio.sleep(0)
    assert not waiting.done()
    slot.put(2)
    assert await asyncio.wait_for(waiting, 1) == (2, 2)


async def test_every_waiting_reader_wakes_and_a_cancelled_one_harms_none():
    slot: Newest[int] = Newest()
    readers = [asyncio.create_task(slot.newer(0)) for _ in range(3)]
    await asyncio.sleep(0)
    readers[0].cancel()
    slot.put(7)
    done = await asyncio.gather(*readers, return_exceptions=True)
    assert isinstance(done[0], asyncio.CancelledError)
    assert done[1:] == [(1, 7), (1, 7)]


async def test_closing_ends_every_reader():
    slot: Newest[int] = Newest()
    waiting = asyncio.create_task(slot.newer(0))
    await asyncio.sleep(0)
    slot.close()
    with pytest.raises(Closed):
        await asyncio.wait_for(waiting, 1)
