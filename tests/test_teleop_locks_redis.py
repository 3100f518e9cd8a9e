"""Teleop locks in Redis (scaled mode) across a Redis restart, on a redis-server of the
test's own: the holder's process holds its lock again from its live connection, while a
lock withdrawn (STOP) or taken by another stays with them."""

from __future__ import annotations

import asyncio
import contextlib
from collections.abc import AsyncIterator
from typing import Any

import pytest

from telemetry.rosbridge.relay import shared_redis
from telemetry.rosbridge.teleop_locks import RedisLockStore, TeleopLocks
from tests.fixtures_live import PrivateRedis, until

pytestmark = [pytest.mark.scaled, pytest.mark.slow]

TTL = 3.0  # the lock's TTL: renewed at most every TTL / 3 while its holder drives
ROBOT = "r1"


def process(redis: Any, stops: list[str]) -> TeleopLocks:
    """One server process's locks on the shared Redis."""
    return TeleopLocks(RedisLockStore(redis), stop=stops.append, ttl=TTL, silence=0.5)


@contextlib.asynccontextmanager
async def driving(locks: TeleopLocks, connection: str) -> AsyncIterator[None]:
    """The holder on ``connection`` sends a moving ``cmd_vel`` every 0.1 s, as a page
    does, for as long as its lock passes them."""

    async def drive() -> None:
        while locks.accepts(ROBOT, connection):
            locks.commanded(ROBOT, moving=True)
            await asyncio.sleep(0.1)  # the page's command rate

    task = asyncio.create_task(drive())
    try:
        yield
    finally:
        task.cancel()
        with contextlib.suppress(asyncio.CancelledError):
            await task


async def restart(redis_server: PrivateRedis) -> None:
    await asyncio.to_thread(redis_server.restart)


@pytest.fixture
async def redis_client(private_redis: PrivateRedis) -> AsyncIterator[Any]:
    client = shared_redis(private_redis.url)
    yield client
    await client.aclose()


async def test_the_holder_holds_its_lock_again_after_redis_restarts_empty(
    private_redis: PrivateRedis, redis_client: Any
) -> None:
    here, elsewhere = process(redis_client, []), process(redis_client, [])
    assert await here.acquire(ROBOT, "c1", "user:operator") == (True, "user:operator")
    async with driving(here, "c1"):
        await restart(private_redis)
        assert await elsewhere.holder(ROBOT) == ""  # Redis came back empty

        async def held_again() -> bool:
            return await elsewhere.holder(ROBOT) == "user:operator"

        await until(held_again, "the lock held again by its holder", TTL)
        assert await elsewhere.acquire(ROBOT, "c2", "user:operator2") == (False, "user:operator")
        assert here.accepts(ROBOT, "c1")  # the holder's commands still pass


async def test_a_lock_withdrawn_by_stop_is_not_brought_back_by_its_holders_renewal(
    private_redis: PrivateRedis, redis_client: Any
) -> None:
    stops: list[str] = []
    here, elsewhere = process(redis_client, stops), process(redis_client, [])
    await here.acquire(ROBOT, "c1", "user:operator")
    async with driving(here, "c1"):
        await restart(private_redis)
        # STOP on the other process before the holder's next renewal: a lock withdrawn from
        # a Redis that restarted must not read as one lost with Redis.
        assert await elsewhere.withdraw(ROBOT, keep="c2") == ""
        await until(lambda: not here.accepts(ROBOT, "c1"), "the holder let go", TTL)
    assert await elsewhere.holder(ROBOT) == ""
    assert ROBOT in stops  # the holder's process stopped the robot as it let go


async def test_a_lock_another_took_after_the_restart_stays_theirs(
    private_redis: PrivateRedis, redis_client: Any
) -> None:
    here, elsewhere = process(redis_client, []), process(redis_client, [])
    await here.acquire(ROBOT, "c1", "user:operator")
    async with driving(here, "c1"):
        await restart(private_redis)
        assert await elsewhere.acquire(ROBOT, "c2", "user:operator2") == (True, "user:operator2")
        await until(lambda: not here.accepts(ROBOT, "c1"), "the first holder let go", TTL)
    assert await here.holder(ROBOT) == "user:operator2"
