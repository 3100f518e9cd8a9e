"""Scaled mode: an export served by one process asks the processes its robots are connected
to (each records its own robots) to write out what they hold of them first, so the export
holds everything recorded up to the request wherever the robot is.

The robots' processes are found in the relay's directory in Redis (each live process's
``robots`` hash); each is sent ``rb.flush_recording`` on its channel and answers
``rb.flushed`` on a reply channel once its recorder flushed (``Hub.flush_recording``).
"""

from __future__ import annotations

import asyncio
import contextlib
from typing import Any

from asgiref.sync import async_to_sync
from channels.layers import get_channel_layer

from telemetry.domain import names

FLUSH_REQUEST = "rb.flush_recording"
FLUSHED = "rb.flushed"


def flush_elsewhere(redis_url: str, robots: list[str], timeout: float = 5.0) -> int:
    """Ask the processes ``robots`` are connected to to flush their recordings, waiting at
    most ``timeout`` seconds in all; return how many answered."""
    return int(async_to_sync(_flush_elsewhere)(redis_url, robots, timeout))


async def _flush_elsewhere(redis_url: str, robots: list[str], seconds: float) -> int:
    owners = await _owners(redis_url, robots)
    if not owners:
        return 0
    layer = get_channel_layer()
    reply = await layer.new_channel()
    for channel in owners:
        await layer.send(channel, {"type": FLUSH_REQUEST, "robots": robots, "reply": reply})
    answered = 0
    with contextlib.suppress(TimeoutError):
        async with asyncio.timeout(seconds):
            while answered < len(owners):
                if (await layer.receive(reply)).get("type") == FLUSHED:
                    answered += 1
    return answered


async def _owners(redis_url: str, robots: list[str]) -> list[str]:
    """The channels of the live processes that have one of ``robots`` connected."""
    from redis.asyncio import from_url

    redis: Any = from_url(redis_url)
    try:
        found = []
        for raw in await redis.smembers(names.redis_key("processes")):
            channel = raw.decode() if isinstance(raw, bytes) else str(raw)
            if not await redis.exists(names.redis_key("alive", channel)):
                continue
            held = await redis.hmget(names.redis_key("robots", channel), robots)
            if any(value is not None for value in held):
                found.append(channel)
        return found
    finally:
        await redis.aclose()
