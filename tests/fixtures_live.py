"""Rosbridge fixtures: in-process clients through the real ASGI application, and live servers.

In-process (``rosbridge``): ``await rosbridge(token=...)`` or ``await rosbridge(user=...)``
opens a ``channels.testing.WebsocketCommunicator`` on the real application and returns a
``RosClient`` speaking rosbridge JSON. Tests using it need ``transactional_db``: the consumer
reads the database from other threads.

Live servers: see the second half of this module.
"""

from __future__ import annotations

import asyncio
import json
from collections.abc import AsyncIterator, Awaitable, Callable
from typing import Any

import cbor2
import pytest
from channels.testing import WebsocketCommunicator
from django.contrib.auth.models import User
from django.test import Client

TIMEOUT = 3.0


class Refused(Exception):
    """The server refused the WebSocket handshake."""


class RosClient:
    """A rosbridge client over a WebsocketCommunicator."""

    def __init__(self, communicator: WebsocketCommunicator) -> None:
        self.communicator = communicator

    async def send(self, **frame: Any) -> None:
        await self.communicator.send_to(text_data=json.dumps(frame))

    async def send_raw(self, text: str) -> None:
        await self.communicator.send_to(text_data=text)

    async def receive(self, wait: float = TIMEOUT) -> dict[str, Any]:
        """Return the next frame, JSON or CBOR, decoded."""
        message = await self.communicator.receive_output(wait)
        if message["type"] != "websocket.send":
            raise AssertionError(f"expected a frame, got {message}")
        if message.get("text") is not None:
            return json.loads(message["text"])  # type: ignore[no-any-return]
        return cbor2.loads(message["bytes"])  # type: ignore[no-any-return]

    async def receive_raw(self, wait: float = TIMEOUT) -> dict[str, Any]:
        return await self.communicator.receive_output(wait)  # type: ignore[no-any-return]

    async def receive_until(
        self, predicate: Callable[[dict[str, Any]], bool], wait: float = TIMEOUT
    ) -> dict[str, Any]:
        """Return the first frame matching ``predicate``, skipping others, within ``wait``."""
        async with asyncio.timeout(wait):
            while True:
                frame = await self.receive(wait)
                if predicate(frame):
                    return frame

    async def nothing_more(self, wait: float = 0.2) -> bool:
        """True if no frame arrives within ``wait`` (for checks that something is dropped)."""
        return await self.communicator.receive_nothing(wait)  # type: ignore[no-any-return]

    async def call(self, service: str, args: Any = None, id: str = "call") -> dict[str, Any]:
        """Call a service and return its ``service_response``."""
        await self.send(op="call_service", id=id, service=service, args=args or {})
        return await self.receive_until(
            lambda f: f.get("op") == "service_response" and f.get("id") == id
        )

    async def quiet(self) -> bool:
        """True if nothing was sent to this client before a round trip started now.

        Frames to one client are delivered in order, so once the sender of a frame has
        ``sync``-ed, this tells without waiting whether that frame reached this client.
        """
        await self.send(op="call_service", id="quiet", service="/rosapi/get_time")
        frame = await self.receive()
        if frame.get("op") == "service_response" and frame.get("id") == "quiet":
            return True
        await self.receive_until(lambda f: f.get("id") == "quiet")
        return False

    async def sync(self) -> None:
        """Return once the server has handled every frame sent so far on this connection."""
        await self.call("/rosapi/get_time", id="sync")

    async def close(self) -> None:
        await self.communicator.disconnect()


def session_cookie(user: User) -> bytes:
    client = Client()
    client.force_login(user)
    return f"sessionid={client.cookies['sessionid'].value}".encode()


Connect = Callable[..., Awaitable[RosClient]]


@pytest.fixture
async def rosbridge() -> AsyncIterator[Connect]:
    """Open rosbridge connections through the real ASGI application; all closed at the end.

    ``await rosbridge(token=...)`` (query string), ``header_token=...`` (Authorization),
    ``user=...`` (session, with an ``origin`` defaulting to ours), ``path=...``.
    Raises Refused when the handshake is refused.
    """
    from channels.db import database_sync_to_async

    from cloudnav_web.asgi import application

    opened: list[RosClient] = []

    async def connect(
        token: str | None = None,
        header_token: str | None = None,
        user: User | None = None,
        origin: str | None = "http://testserver",
        path: str = "/rosbridge",
    ) -> RosClient:
        headers: list[tuple[bytes, bytes]] = []
        if token is not None:
            path += f"?token={token}"
        if header_token is not None:
            headers.append((b"authorization", f"Token {header_token}".encode()))
        if user is not None:
            headers.append((b"cookie", await database_sync_to_async(session_cookie)(user)))
        if origin is not None:
            headers.append((b"origin", origin.encode()))
        communicator = WebsocketCommunicator(application, path, headers=headers)
        connected, _ = await communicator.connect(timeout=TIMEOUT)
        if not connected:
            await communicator.disconnect(timeout=TIMEOUT)
            raise Refused(path)
        client = RosClient(communicator)
        opened.append(client)
        return client

    yield connect
    for client in opened:
        await client.close()
