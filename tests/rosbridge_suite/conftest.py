"""Clients for the reproduced rosbridge_suite tests: raw WebSockets, as in the originals."""

from __future__ import annotations

import asyncio
import json
from collections.abc import AsyncIterator, Awaitable, Callable
from typing import Any

import pytest
import websockets

from tests.fixtures_live import LiveServer, session_cookie

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


@pytest.fixture
def admin_headers(daphne_server: LiveServer, admin: Any) -> dict[str, str]:
    return {"Cookie": session_cookie(admin).decode(), "Origin": daphne_server.url}


@pytest.fixture
async def make_client(
    daphne_server: LiveServer, admin_headers: dict[str, str]
) -> AsyncIterator[MakeClient]:
    headers = admin_headers
    opened: list[WsClient] = []

    async def make() -> WsClient:
        socket = await websockets.connect(daphne_server.rosbridge_url(), additional_headers=headers)
        opened.append(WsClient(socket))
        return opened[-1]

    yield make
    for client in opened:
        await client.close()


@pytest.fixture
async def node(make_client: MakeClient) -> WsClient:
    """The client that plays the ROS node of the original tests."""
    return await make_client()
