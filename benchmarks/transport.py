"""Cross-process transports on Redis: messages/s from one sender to one receiver, and CPU.

The alternatives the scaled mode's relay chose between (``telemetry/rosbridge/relay.py``):
channels_redis' ``RedisChannelLayer`` and ``RedisPubSubChannelLayer`` (one ``group_send``
per message), and Redis pub/sub through redis-py's asyncio client, one ``PUBLISH`` per round trip
(``--batch 1``) or pipelined, ``--batch`` messages per round trip. Sender and receiver run
in this one process, so ``msg_per_s`` counts both ends' work on one core, and
``cpu_ms_per_1000`` is this process's CPU time per 1,000 messages carried (Redis's own CPU
not counted). ``--redis-url`` names a database this benchmark may write to.
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import json
import time
from collections.abc import Awaitable, Callable
from typing import Any

TRANSPORTS = ("channel-layer", "pubsub-channel-layer", "pubsub")
POSE = {
    "header": {"stamp": {"sec": 1, "nanosec": 2}, "frame_id": "bench/Floor"},
    "pose": {
        "position": {"x": 1.0, "y": 2.0, "z": 0.0},
        "orientation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0},
    },
}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--transport", choices=TRANSPORTS, default="pubsub")
    parser.add_argument("--batch", type=int, default=50, help="pubsub: messages per round trip")
    parser.add_argument("--messages", type=int, default=3000)
    parser.add_argument("--redis-url", default="redis://127.0.0.1:6379/0")
    parser.add_argument("--json", action="store_true", help="print one JSON object")


def run(options: dict[str, Any]) -> None:
    found = asyncio.run(measure(options))
    if options.get("json"):
        print(json.dumps(found))
    else:
        print(
            f"{found['transport']} (batch {found['batch']}): {found['received']} of "
            f"{found['sent']}, {found['msg_per_s']} msg/s, {found['cpu_ms_per_1000']} ms CPU "
            "per 1,000"
        )


async def measure(options: dict[str, Any]) -> dict[str, Any]:
    count, transport = options["messages"], options["transport"]
    batch = options["batch"] if transport == "pubsub" else 1
    if transport == "pubsub":
        send, receive = await _pubsub(options["redis_url"])
    else:
        send, receive = await _layer(options["redis_url"], transport)
    received = 0

    async def receiver() -> None:
        nonlocal received
        while received < count:
            await receive()
            received += 1

    reading = asyncio.create_task(receiver())
    started, cpu = time.perf_counter(), time.process_time()
    for first in range(0, count, batch):
        await send(list(range(first, min(count, first + batch))))
    with contextlib.suppress(TimeoutError):  # what arrived is counted
        await asyncio.wait_for(reading, 120)
    wall, cpu = time.perf_counter() - started, time.process_time() - cpu
    return {
        "transport": transport,
        "batch": batch,
        "sent": count,
        "received": received,
        "msg_per_s": round(received / wall),
        "cpu_ms_per_1000": round(1e6 * cpu / received, 1) if received else None,
    }


Send = Callable[[list[int]], Awaitable[None]]
Receive = Callable[[], Awaitable[Any]]


async def _layer(url: str, transport: str) -> tuple[Send, Receive]:
    from channels_redis.core import RedisChannelLayer
    from channels_redis.pubsub import RedisPubSubChannelLayer

    kind = RedisChannelLayer if transport == "channel-layer" else RedisPubSubChannelLayer
    sender, receiver = kind(hosts=[url]), kind(hosts=[url])
    channel = await receiver.new_channel("bench.process")
    await receiver.group_add("bench.topic", channel)

    async def send(seqs: list[int]) -> None:
        for seq in seqs:
            await sender.group_send("bench.topic", {"type": "rb.publish", "msg": POSE, "i": seq})

    return send, lambda: receiver.receive(channel)


async def _pubsub(url: str) -> tuple[Send, Receive]:
    from redis.asyncio import from_url

    sender, listener = from_url(url), from_url(url)
    pubsub = listener.pubsub(ignore_subscribe_messages=True)
    await pubsub.subscribe("bench:topic")
    await pubsub.get_message(timeout=1.0)  # the subscription's confirmation

    async def send(seqs: list[int]) -> None:
        async with sender.pipeline(transaction=False) as pipe:
            for seq in seqs:
                pipe.publish("bench:topic", json.dumps({"msg": POSE, "i": seq}))
            await pipe.execute()

    async def receive() -> Any:
        while (message := await pubsub.get_message(timeout=None)) is None:
            pass
        return message

    return send, receive
