"""Hostile frames and the live-server checks the hostile-input tests share.

The frames are built byte by byte where a well-behaved encoder would refuse to build them
(CBOR shared references, tags, deep nesting). ``LiveRosbridge`` is a real socket to a real
daphne process; ``server_memory`` reads that process's resident memory with psutil.
"""

from __future__ import annotations

import asyncio
import json
import struct
from typing import TYPE_CHECKING, Any

import cbor2
import psutil
import websockets

if TYPE_CHECKING:
    from tests.fixtures_live import LiveServer

ANSWER_DEADLINE = 5.0


def cbor_head(major: int, argument: int) -> bytes:
    """The initial bytes of a CBOR item: its major type and argument (RFC 8949 section 3)."""
    if argument < 24:
        return bytes([major << 5 | argument])
    for info, fmt in ((24, "!B"), (25, "!H"), (26, "!I"), (27, "!Q")):
        if argument < 1 << (8 * struct.calcsize(fmt)):
            return bytes([major << 5 | info]) + struct.pack(fmt, argument)
    raise ValueError(argument)


def cbor_tag(number: int, item: bytes) -> bytes:
    return cbor_head(6, number) + item


def shared_reference_bomb(levels: int = 64) -> bytes:
    """A CBOR item of ``2**levels`` leaves in a few hundred bytes: each level is an array of
    two copies of the level below, the second one a shared reference (tags 28 and 29) to
    the first."""
    inner = cbor_tag(28, b"\x82\x00\x00")
    for index in reversed(range(levels - 1)):
        inner = cbor_tag(28, cbor_head(4, 2) + inner + cbor_tag(29, cbor_head(0, index + 1)))
    return inner


def cbor_frame(fields: dict[str, Any], **raw: bytes) -> bytes:
    """A CBOR map of ``fields`` (encoded by cbor2) and ``raw`` (already encoded items)."""
    items = b"".join(cbor2.dumps(k) + cbor2.dumps(v) for k, v in fields.items())
    items += b"".join(cbor2.dumps(k) + v for k, v in raw.items())
    return cbor_head(5, len(fields) + len(raw)) + items


class LiveRosbridge:
    """A rosbridge client on a real WebSocket to a live server."""

    def __init__(self, ws: websockets.ClientConnection) -> None:
        self.ws = ws
        self._calls = 0

    @classmethod
    async def connect(cls, server: LiveServer, token: str) -> LiveRosbridge:
        ws = await websockets.connect(
            server.rosbridge_url(token), max_size=None, open_timeout=ANSWER_DEADLINE
        )
        return cls(ws)

    async def send(self, frame: dict[str, Any] | str | bytes) -> None:
        await self.ws.send(json.dumps(frame) if isinstance(frame, dict) else frame)

    async def receive(self, wait: float = ANSWER_DEADLINE) -> dict[str, Any]:
        data = await asyncio.wait_for(self.ws.recv(), wait)
        decoded: dict[str, Any] = json.loads(data) if isinstance(data, str) else cbor2.loads(data)
        return decoded

    async def answers(self, wait: float = ANSWER_DEADLINE) -> bool:
        """True if a ``get_time`` call is answered within ``wait`` seconds (other frames that
        arrive first are skipped)."""
        self._calls += 1
        call_id = f"alive-{self._calls}"
        try:
            await self.send({"op": "call_service", "id": call_id, "service": "/rosapi/get_time"})
            async with asyncio.timeout(wait):
                while (await self.receive(wait)).get("id") != call_id:
                    pass
        except (TimeoutError, websockets.ConnectionClosed):
            return False
        return True

    async def close(self) -> None:
        await self.ws.close()


def server_memory(server: LiveServer) -> int:
    """The live server process's resident memory, in bytes."""
    return int(psutil.Process(server.process.pid).memory_info().rss)
