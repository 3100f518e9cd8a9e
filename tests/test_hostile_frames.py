"""Hostile rosbridge frames against a live server: none stalls it, none grows its memory.

Each test sends its frames over a real socket to daphne in its own process, then checks
that the sender and a bystander are both still answered and that the server's memory
stayed within a bound.
"""

from __future__ import annotations

import pytest

from tests.conftest import make_robot
from tests.hostile import (
    LiveRosbridge,
    cbor_frame,
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
    "arguments of a call": cbor_frame(
        {"op": "call_service", "id": "c", "service": "/rosapi/get_param"},
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
    await attacker.send({"op": "set_level", "level": "error"})
    assert await bystander.answers()
    before = server_memory(daphne_server)
    await attacker.send(frame)
    assert await attacker.answers()
    assert await bystander.answers()
    assert server_memory(daphne_server) - before < MEMORY_BOUND
    await attacker.close()
    await bystander.close()
