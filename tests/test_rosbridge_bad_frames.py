"""Bad frames are logged and dropped as rosbridge drops them; the connection keeps working."""

from __future__ import annotations

import json

import pytest

from tests.conftest import make_robot

pytestmark = pytest.mark.django_db(transaction=True)

BAD_FRAMES = [
    "not json at all",
    "42",
    "[1, 2, 3]",
    '"a string"',
    "null",
    json.dumps({"topic": "/r1/pose"}),
    json.dumps({"op": "teleport"}),
    json.dumps({"op": 7}),
    json.dumps({"op": "subscribe", "topic": 5}),
    json.dumps({"op": "subscribe", "topic": "pose", "throttle_rate": "fast"}),
    json.dumps({"op": "subscribe", "topic": "pose", "compression": "zip"}),
    json.dumps({"op": "publish", "topic": "pose", "msg": [1, 2]}),
    json.dumps({"op": "publish", "topic": "no spaces allowed", "msg": {}}),
    json.dumps({"op": "advertise", "topic": "pose"}),
    json.dumps({"op": "fragment", "id": "f", "data": "x", "num": 3, "total": 2}),
    json.dumps({"op": "set_level", "level": "loud"}),
]


@pytest.fixture
def robot(rosbridge, building):
    token = make_robot(name="r1", buildings=[building])[1]

    async def connect():
        return await rosbridge(token=token)

    return connect


@pytest.mark.parametrize("text", BAD_FRAMES)
async def test_it_drops_a_bad_frame_silently_and_keeps_the_connection(robot, text):
    client = await robot()
    await client.send_raw(text)
    response = await client.call("/rosapi/get_time")
    assert response["result"] is True


@pytest.mark.parametrize("text", BAD_FRAMES)
async def test_it_reports_a_bad_frame_to_a_client_that_asked(robot, text):
    client = await robot()
    await client.send(op="set_level", level="error")
    await client.send_raw(text)
    status = await client.receive()
    assert status["op"] == "status"
    assert status["level"] == "error"


async def test_status_level_none_silences_reports(robot):
    client = await robot()
    await client.send(op="set_level", level="error")
    await client.send(op="set_level", level="none")
    await client.send_raw("42")
    assert await client.quiet()


async def test_a_status_carries_the_frames_id(robot):
    client = await robot()
    await client.send(op="set_level", level="info")
    await client.send(op="subscribe", id="sub-7", topic="mystery")
    status = await client.receive()
    assert status["id"] == "sub-7"


async def test_a_frame_over_the_size_limit_is_dropped(robot, settings):
    settings.CLOUDNAV_ROSBRIDGE_MAX_FRAME_BYTES = 2000
    client = await robot()
    await client.send(op="set_level", level="error")
    await client.send(op="subscribe", topic="odom")
    await client.send(op="publish", topic="odom", msg={"data": "x" * 5000})
    assert "limit" in (await client.receive())["msg"]
    await client.send(op="publish", topic="odom", msg={"data": "small"})
    assert (await client.receive())["msg"] == {"data": "small"}


async def test_a_failed_service_call_answers_result_false_with_the_reason(robot):
    client = await robot()
    response = await client.call("/no/such/service", {})
    assert response == {
        "op": "service_response",
        "id": "call",
        "service": "/no/such/service",
        "values": "Service /no/such/service does not exist",
        "result": False,
    }


async def test_a_service_call_with_a_bad_name_answers_result_false(robot):
    client = await robot()
    response = await client.call("bad name!", {})
    assert response["result"] is False
    assert "not a valid ROS name" in response["values"]


async def test_a_goal_to_a_missing_action_fails_as_a_result(robot):
    client = await robot()
    await client.send(op="send_action_goal", id="g1", action="/nowhere", action_type="x/Y", args={})
    result = await client.receive()
    assert result["op"] == "action_result"
    assert result["id"] == "g1"
    assert result["result"] is False


async def test_no_status_is_sent_unasked(robot):
    client = await robot()
    for text in BAD_FRAMES:
        await client.send_raw(text)
    assert await client.quiet()
