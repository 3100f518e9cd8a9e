"""Two rosbridge processes sharing Redis (the scaled mode): the ``cluster`` and ``connect``
fixtures (a pytest plugin of tests/conftest.py) and the client they connect."""

from __future__ import annotations

import asyncio
import json
from contextlib import AsyncExitStack

import pytest
import websockets

WAIT = 5.0


class Client:
    def __init__(self, socket):
        self.socket = socket

    async def send(self, **frame):
        await self.socket.send(json.dumps(frame))

    async def receive(self, wait=WAIT):
        return json.loads(await asyncio.wait_for(self.socket.recv(), wait))

    async def call(self, service, args=None, id="call"):
        await self.send(op="call_service", id=id, service=service, args=args or {})
        while (frame := await self.receive()).get("id") != id:
            pass
        return frame

    async def sync(self):
        await self.call("/rosapi/get_time", id="sync")

    async def poses(self, count, wait=WAIT):
        """Return the sequence numbers of the next ``count`` poses."""
        return [(await self.receive(wait))["msg"]["header"]["seq"] for _ in range(count)]


@pytest.fixture
def cluster(scaled_servers):
    return scaled_servers(2)


@pytest.fixture
async def connect(cluster):
    async with AsyncExitStack() as stack:

        async def open_as(who, server):
            live = cluster.servers[server]  # looked up now: a replaced process's successor
            if who in cluster.tokens:
                url, headers = live.rosbridge_url(cluster.tokens[who]), {}
            else:
                url, headers = (
                    live.rosbridge_url(),
                    {"Cookie": cluster.cookies[who], "Origin": live.url},
                )
            socket = await stack.enter_async_context(
                websockets.connect(url, additional_headers=headers)
            )
            return Client(socket)

        yield open_as
