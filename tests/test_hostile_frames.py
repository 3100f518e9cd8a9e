"""Hostile rosbridge frames against a live server: none stalls it, none grows its memory.

Each test sends its frames over a real socket to daphne in its own process, then checks
that the sender and a bystander are both still answered and that the server's memory
stayed within a bound.
"""

from __future__ import annotations

import asyncio

import cbor2
import pytest
import websockets
from channels.db import database_sync_to_async

from tests.conftest import make_robot
from tests.fixtures_live import session_cookie
from tests.hostile import (
    LiveRosbridge,
    cbor_frame,
    cbor_head,
    server_memory,
    shared_reference_bomb,
)

MEMORY_BOUND = 64 * 2**20


@pytest.fixture
def tokens(building):
    return {name: make_robot(name=name, buildings=[building])[1] for name in ("r1", "r2")}


BOMBS = {
    "id of a failing call": cbor_frame(
        {"op": "call_service", "service": "/rosapi/get_time", "args": 5},
        id=shared_reference_bomb(),
    ),
    "id of an unknown op": cbor_frame({"op": "teleport"}, id=shared_reference_bomb()),
    "message to a subscriber": cbor_frame(
        {"op": "publish", "topic": "odom"}, msg=cbor_frame({}, data=shared_reference_bomb())
    ),
    "arguments to a provider": cbor_frame(
        {"op": "call_service", "id": "c", "service": "/r1/trigger"},
        args=cbor_frame({}, name=shared_reference_bomb()),
    ),
}


@pytest.mark.parametrize("frame", BOMBS.values(), ids=BOMBS.keys())
async def test_a_shared_reference_bomb_neither_stalls_the_server_nor_grows_it(
    daphne_server, tokens, frame
):
    attacker = await LiveRosbridge.connect(daphne_server, tokens["r1"])
    bystander = await LiveRosbridge.connect(daphne_server, tokens["r2"])
    await bystander.send({"op": "subscribe", "topic": "/r1/odom", "type": "nav_msgs/Odometry"})
    await attacker.send(
        {"op": "advertise_service", "service": "trigger", "type": "std_srvs/Trigger"}
    )
    await attacker.send({"op": "set_level", "level": "error"})
    assert await bystander.answers()
    before = server_memory(daphne_server)
    await attacker.send(frame)
    assert await attacker.answers()
    assert await bystander.answers()
    assert server_memory(daphne_server) - before < MEMORY_BOUND
    await attacker.close()
    await bystander.close()


async def refused(client: LiveRosbridge, wait: float = 2.0) -> str | None:
    """Return the message of the next error ``status`` (or failed answer), if any."""
    try:
        while True:
            frame = await client.receive(wait)
            if frame.get("op") == "status":
                return str(frame["msg"])
            if frame.get("result") is False:
                return str(frame["values"])
    except TimeoutError:
        return None


def fragment(message: str, num: int, total: int, data: str) -> dict[str, object]:
    return {"op": "fragment", "id": message, "num": num, "total": total, "data": data}


async def test_fragments_never_completed_are_bounded_per_connection_and_in_total(
    daphne_servers, tokens
):
    server = daphne_servers.start(
        env={
            "CLOUDNAV_ROSBRIDGE_FRAGMENT_BYTES": str(2 * 2**20),
            "CLOUDNAV_ROSBRIDGE_FRAGMENT_BYTES_TOTAL": str(3 * 2**20),
            "CLOUDNAV_ROSBRIDGE_FRAGMENT_TIMEOUT": "1.5",
        }
    )
    piece = "x" * (256 * 2**10)
    greedy, first, second = [
        await LiveRosbridge.connect(server, tokens[r]) for r in ("r1", "r2", "r1")
    ]
    before = server_memory(server)
    for client in (greedy, first, second):
        await client.send({"op": "set_level", "level": "error"})
    for num in range(8):  # just over 2 MiB: the last piece is refused, the message dropped
        await greedy.send(fragment("huge", num, 1000, piece))
    assert "this connection" in (await refused(greedy) or "")
    assert await greedy.answers()
    for num in range(7):  # 1.75 MiB: within this connection's share
        await first.send(fragment("m", num, 1000, piece))
    assert await refused(first, wait=0.5) is None
    for num in range(7):
        await second.send(fragment("m", num, 1000, piece))
    assert "the server holds" in (await refused(second) or "")
    for client in (greedy, first, second):
        assert await client.answers()
    assert server_memory(server) - before < MEMORY_BOUND
    # Nothing more arrives on the first connection, yet its pieces expire on a timer: the
    # server has room again.
    await asyncio.sleep(2.0)
    for num in range(7):
        await second.send(fragment("again", num, 1000, piece))
    assert await refused(second, wait=0.5) is None
    for client in (greedy, first, second):
        await client.close()


async def test_a_tiny_fragment_size_gets_fragments_of_the_least_size(daphne_server, tokens):
    robot = await LiveRosbridge.connect(daphne_server, tokens["r1"])
    await robot.send({"op": "subscribe", "topic": "odom", "fragment_size": 1})
    await robot.send({"op": "publish", "topic": "odom", "msg": {"data": "z" * 100_000}})
    first = await robot.receive()
    assert first["op"] == "fragment"
    assert len(first["data"]) >= 1024
    assert first["total"] <= 100
    assert await robot.answers()
    await robot.close()


async def test_subscriptions_past_the_limit_are_refused_and_the_connection_stays(
    daphne_servers, tokens
):
    server = daphne_servers.start(env={"CLOUDNAV_ROSBRIDGE_MAX_SUBSCRIPTIONS": "50"})
    robot = await LiveRosbridge.connect(server, tokens["r1"])
    await robot.send({"op": "set_level", "level": "error"})
    for n in range(51):
        await robot.send({"op": "subscribe", "id": f"s{n}", "topic": "odom"})
    assert "subscriptions" in (await refused(robot) or "")
    assert await robot.answers()
    await robot.close()


async def test_a_frame_of_millions_of_empty_arrays_is_refused_before_it_is_built(
    daphne_server, tokens
):
    count = 4_000_000  # one byte each in CBOR, some 60 bytes each once decoded
    arrays = cbor_head(5, 1) + cbor2.dumps("data") + cbor_head(4, count) + b"\x80" * count
    robot = await LiveRosbridge.connect(daphne_server, tokens["r1"])
    await robot.send({"op": "set_level", "level": "error"})
    before = server_memory(daphne_server)
    await robot.send(cbor_frame({"op": "publish", "topic": "odom"}, msg=arrays))
    assert "values" in (await refused(robot) or "")
    assert await robot.answers()
    assert server_memory(daphne_server) - before < MEMORY_BOUND
    await robot.close()


async def test_one_viewers_many_sockets_hold_no_more_than_their_share_of_fragments(
    daphne_servers, tokens, viewer
):
    server = daphne_servers.start(
        env={
            "CLOUDNAV_ROSBRIDGE_FRAGMENT_BYTES": str(2**20),
            "CLOUDNAV_ROSBRIDGE_FRAGMENT_BYTES_TOTAL": str(4 * 2**20),
            "CLOUDNAV_ROSBRIDGE_FRAGMENT_BYTES_PER_CLIENT": str(2 * 2**20),
        }
    )
    piece = "x" * (128 * 2**10)
    cookie = await database_sync_to_async(session_cookie)(viewer)
    handshake = {"Cookie": cookie.decode(), "Origin": server.url}
    url = server.rosbridge_url()
    sockets = [
        LiveRosbridge(await websockets.connect(url, additional_headers=handshake)) for _ in range(4)
    ]
    refusals = []
    for index, socket in enumerate(sockets):
        await socket.send({"op": "set_level", "level": "error"})
        for num in range(7):  # 0.875 MiB each: the third socket passes the viewer's 2 MiB
            await socket.send(fragment(f"v{index}", num, 1000, piece))
        refusals.append(await refused(socket, wait=1.0))
    assert refusals[:2] == [None, None]
    assert "this client's connections" in (refusals[2] or "")
    robot = await LiveRosbridge.connect(server, tokens["r1"])
    for num in range(7):  # the robot still finds room in the server's budget
        await robot.send(fragment("map", num, 1000, piece))
    assert await refused(robot, wait=1.0) is None
    for client in (*sockets, robot):
        assert await client.answers()
        await client.close()
