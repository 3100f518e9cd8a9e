"""Back-pressure: a subscriber that stops reading neither delays the others nor grows the
server's memory; its bounded send queue drops its oldest frames instead.

Over real sockets against daphne: the stalled subscriber is a raw socket with a tiny
receive buffer that completes the handshake, subscribes, and never reads again.
"""

from __future__ import annotations

import asyncio
import base64
import json
import os
import socket
import struct
import time

import psutil
import pytest
import websockets

from tests.conftest import make_robot

MESSAGE_BYTES = 20_000
MESSAGES = 5_000  # 100 MB through the topic: far beyond any buffer the stalled one has
WINDOW = 8


def masked_frame(text: str) -> bytes:
    """A client-to-server text frame (clients must mask, RFC 6455 section 5.3)."""
    payload = text.encode()
    mask = os.urandom(4)
    body = bytes(b ^ mask[i % 4] for i, b in enumerate(payload))
    size = len(payload)
    header = bytes((0x81, 0x80 | size)) if size < 126 else struct.pack("!BBH", 0x81, 0xFE, size)
    return header + mask + body


def stalled_subscriber(host: str, port: int, token: str, topic: str) -> socket.socket:
    """Open a rosbridge connection, subscribe to ``topic``, and never read again."""
    sock = socket.socket()
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
    sock.connect((host, port))
    key = base64.b64encode(os.urandom(16)).decode()
    sock.sendall(
        f"GET /rosbridge?token={token} HTTP/1.1\r\nHost: {host}:{port}\r\n"
        f"Upgrade: websocket\r\nConnection: Upgrade\r\nSec-WebSocket-Key: {key}\r\n"
        "Sec-WebSocket-Version: 13\r\n\r\n".encode()
    )
    response = b""
    while b"\r\n\r\n" not in response:
        response += sock.recv(1)  # byte by byte: read nothing past the handshake
    assert response.startswith(b"HTTP/1.1 101"), response
    sock.sendall(masked_frame(json.dumps({"op": "subscribe", "topic": topic})))
    return sock


@pytest.fixture
def server(daphne_servers):
    return daphne_servers.start(
        env={
            "CLOUDNAV_ROSBRIDGE_SEND_QUEUE_FRAMES": "64",
            "CLOUDNAV_ROSBRIDGE_SEND_QUEUE_BYTES": str(2 * 2**20),
        }
    )


def rss(server) -> int:
    return int(psutil.Process(server.process.pid).memory_info().rss)


@pytest.fixture
def tokens(building):
    return [make_robot(name=name, buildings=[building])[1] for name in ("r1", "r2")]


async def test_a_stalled_subscriber_neither_delays_others_nor_grows_memory(server, tokens):
    robot_token, viewer_token = tokens
    stalled = stalled_subscriber(server.host, server.port, viewer_token, "/r1/scan")
    filler = "x" * MESSAGE_BYTES
    try:
        async with (
            websockets.connect(server.rosbridge_url(robot_token)) as robot,
            websockets.connect(server.rosbridge_url(viewer_token), max_size=None) as healthy,
        ):
            await healthy.send(json.dumps({"op": "subscribe", "topic": "/r1/scan"}))
            await healthy.send(
                json.dumps({"op": "call_service", "id": "s", "service": "/rosapi/get_time"})
            )
            assert json.loads(await healthy.recv())["id"] == "s"
            before = rss(server)

            # The robot keeps at most WINDOW messages in flight, so a delay can only come
            # from the server, not from a backlog the test itself built up.
            in_flight = asyncio.Semaphore(WINDOW)

            async def publish() -> None:
                for n in range(MESSAGES):
                    await in_flight.acquire()
                    msg = {"n": n, "sent": time.time(), "ranges": filler}
                    await robot.send(json.dumps({"op": "publish", "topic": "scan", "msg": msg}))

            async def receive() -> list[float]:
                delays = []
                async with asyncio.timeout(120):
                    for n in range(MESSAGES):
                        frame = json.loads(await healthy.recv())
                        in_flight.release()
                        assert frame["msg"]["n"] == n  # nothing lost, nothing reordered
                        delays.append(time.time() - frame["msg"]["sent"])
                return delays

            delays, _ = await asyncio.gather(receive(), publish())
            grown = rss(server) - before
    finally:
        stalled.close()
    delays.sort()
    # Were the stalled subscriber able to hold the others up, they would stop altogether;
    # the bound leaves room for a busy machine's scheduling hiccups.
    p99 = delays[int(len(delays) * 0.99)]
    assert p99 < 1.0, f"the healthy subscriber's p99 delay was {p99:.3f} s"
    # 100 MB went to the stalled subscriber; its queue holds at most 2 MiB of it.
    assert grown < 30 * 2**20, f"server memory grew by {grown / 2**20:.1f} MiB"
