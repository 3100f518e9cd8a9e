"""The rosbridge endpoint over real sockets, served by daphne in its own process."""

from __future__ import annotations

import asyncio
import json

import pytest
import websockets
from websockets.exceptions import InvalidStatus

from tests.conftest import make_robot

POSE = {"header": {"frame_id": "boccioni_1/Hall"}, "pose": {"position": {"x": 1, "y": 2}}}


@pytest.fixture
def tokens(building):
    return {
        "r1": make_robot(name="r1", buildings=[building])[1],
        "r2": make_robot(name="r2", buildings=[building])[1],
    }


async def receive_json(ws, wait=5.0):
    return json.loads(await asyncio.wait_for(ws.recv(), wait))


async def test_it_refuses_a_handshake_without_credentials(daphne_server):
    with pytest.raises(InvalidStatus) as refused:
        async with websockets.connect(daphne_server.rosbridge_url()):
            pass
    assert refused.value.response.status_code == 403


async def test_it_refuses_a_bad_token_before_any_data(daphne_server):
    with pytest.raises(InvalidStatus):
        async with websockets.connect(daphne_server.rosbridge_url("cnr_bad")):
            pass


async def test_robots_talk_over_real_sockets(daphne_server, tokens):
    async with (
        websockets.connect(daphne_server.rosbridge_url(tokens["r1"])) as r1,
        websockets.connect(daphne_server.rosbridge_url(tokens["r2"], path="/")) as r2,
    ):
        await r2.send(json.dumps({"op": "subscribe", "topic": "/r1/pose"}))
        await r2.send(json.dumps({"op": "call_service", "id": "s", "service": "/rosapi/get_time"}))
        assert (await receive_json(r2))["id"] == "s"
        await r1.send(json.dumps({"op": "publish", "topic": "pose", "msg": POSE}))
        assert await receive_json(r2) == {"op": "publish", "topic": "/r1/pose", "msg": POSE}


async def test_cbor_and_fragments_cross_the_wire(daphne_server, tokens):
    import cbor2

    async with websockets.connect(daphne_server.rosbridge_url(tokens["r1"])) as r1:
        await r1.send(json.dumps({"op": "subscribe", "topic": "pose", "compression": "cbor"}))
        await r1.send(json.dumps({"op": "subscribe", "topic": "odom", "fragment_size": 1024}))
        await r1.send(json.dumps({"op": "publish", "topic": "pose", "msg": POSE}))
        frame = await asyncio.wait_for(r1.recv(), 5)
        assert isinstance(frame, bytes)
        assert cbor2.loads(frame)["msg"] == POSE
        await r1.send(json.dumps({"op": "publish", "topic": "odom", "msg": {"a": "b" * 3000}}))
        first = await receive_json(r1)
        pieces = [first] + [await receive_json(r1) for _ in range(first["total"] - 1)]
        assert json.loads("".join(p["data"] for p in pieces))["msg"] == {"a": "b" * 3000}


async def test_an_oversized_frame_is_dropped_and_a_huge_one_closes_the_connection(
    daphne_servers, tokens
):
    from websockets.exceptions import ConnectionClosed

    server = daphne_servers.start(env={"CLOUDNAV_ROSBRIDGE_MAX_FRAME_BYTES": "10000"})
    async with websockets.connect(server.rosbridge_url(tokens["r1"]), max_size=None) as r1:
        await r1.send(json.dumps({"op": "set_level", "level": "error"}))
        await r1.send(json.dumps({"op": "publish", "topic": "odom", "msg": {"x": "y" * 20_000}}))
        assert "limit" in (await receive_json(r1))["msg"]
        await r1.send(json.dumps({"op": "call_service", "id": "s", "service": "/rosapi/get_time"}))
        assert (await receive_json(r1))["id"] == "s"
        await r1.send(json.dumps({"op": "publish", "topic": "odom", "msg": {"x": "y" * 50_000}}))
        with pytest.raises(ConnectionClosed):
            await receive_json(r1)
