"""How a test sees that the server closed a connection it should refuse."""

from __future__ import annotations

import asyncio
from typing import Any

CLOSE_WITHIN = 1.0


async def closed_soon(client: Any, wait: float = CLOSE_WITHIN) -> bool:
    """True if the server closes ``client`` within ``wait`` seconds (frames before are skipped)."""
    loop = asyncio.get_running_loop()
    deadline = loop.time() + wait
    while True:
        try:
            message = await client.receive_raw(max(0.01, deadline - loop.time()))
        except TimeoutError:
            return False
        if message["type"] == "websocket.close":
            return True
