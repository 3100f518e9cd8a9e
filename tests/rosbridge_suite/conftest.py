"""Clients for the reproduced rosbridge_suite tests: raw WebSockets, as in the originals."""

from __future__ import annotations

import asyncio
import json
from collections.abc import AsyncIterator, Awaitable, Callable
from typing import Any

import pytest
import websockets

from tests.fixtures_live import (
    LiveServer,
    LiveServers,
    flush_redis,
    scaled_redis_url,
    session_cookie,
)

WAIT = 5.0


class WsClient:
    """A raw rosbridge WebSocket client (the originals' ``make_client``)."""

    def __init__(self, socket: Any) -> None:
        self.socket = socket

    async def send_json(self, frame: dict[str, Any], times: int = 1) -> None:
        for _ in range(times):
            await self.socket.send(json.dumps(frame))

    async def expect(self, count: int, wait: float = WAIT) -> list[dict[str, Any]]:
        """Return the next ``count`` frames (the originals' ``expect_messages``)."""
        async with asyncio.timeout(wait):
            return [json.loads(await self.socket.recv()) for _ in range(count)]

    async def settle(self) -> None:
        """Round trip: every frame sent before it has been handled by the server."""
        await self.send_json({"op": "call_service", "id": "settle", "service": "/rosapi/get_time"})
        while (await self.expect(1))[0].get("id") != "settle":
            pass

    async def close(self) -> None:
        await self.socket.close()


MakeClient = Callable[[], Awaitable[WsClient]]


@pytest.fixture(
    params=["embedded", pytest.param("two processes", marks=[pytest.mark.scaled, pytest.mark.live])]
)
def servers(request: pytest.FixtureRequest, daphne_servers: LiveServers) -> list[LiveServer]:
    """One live server (embedded mode), or two in scaled mode sharing Redis: the same
    tests, whichever process each client is on."""
    if request.param == "embedded":
        return [daphne_servers.start()]
    flush_redis(scaled_redis_url())
    return daphne_servers.start_many(2, env={"REDIS_URL": scaled_redis_url()})


@pytest.fixture
def admin_cookie(admin: Any) -> str:
    return session_cookie(admin).decode()


@pytest.fixture
async def make_client(servers: list[LiveServer], admin_cookie: str) -> AsyncIterator[MakeClient]:
    """Clients take the servers in turn: the node on the first, the next on the second."""
    opened: list[WsClient] = []

    async def make() -> WsClient:
        server = servers[len(opened) % len(servers)]
        headers = {"Cookie": admin_cookie, "Origin": server.url}
        socket = await websockets.connect(server.rosbridge_url(), additional_headers=headers)
        opened.append(WsClient(socket))
        return opened[-1]

    yield make
    for client in opened:
        await client.close()


@pytest.fixture
async def node(make_client: MakeClient) -> WsClient:
    """The client that plays the ROS node of the original tests."""
    return await make_client()
