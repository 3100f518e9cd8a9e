"""Scaled mode: two server processes sharing Redis and PostgreSQL behave as one server.

A robot on one process and an operator on the other see each other's topics, services,
actions, latched messages, parameters and teleop locks, whatever the order in which they
subscribe, connect and reconnect, and whichever process restarts.
"""

from __future__ import annotations

import asyncio
import time
from typing import Any

import pytest
import websockets

from tests.support.scaled_rosbridge import WAIT, Client
from tests.support.teleop import ZERO

pytestmark = pytest.mark.scaled

# In the middle of the fleet's sub-map (goals are checked against it where they are sent).
POSE: dict[str, Any] = {
    "header": {"frame_id": "boccioni_1/Hall"},
    "pose": {"position": {"x": 1, "y": 0.75}},
}
GO = {"linear": {"x": 0.3, "y": 0.0, "z": 0.0}, "angular": {"x": 0.0, "y": 0.0, "z": 0.0}}


def pose(seq):
    return {**POSE, "header": {**POSE["header"], "seq": seq}}


async def publish_poses(robot, seqs, period=0.1):
    """Publish one pose per ``period`` seconds (a robot's 10 Hz), numbered ``seqs``."""
    for seq in seqs:
        await robot.send(op="publish", topic="pose", msg=pose(seq))
        await asyncio.sleep(period)


async def test_a_robot_on_one_process_reaches_an_operator_on_the_other(connect):
    robot, operator = await connect("r1", 0), await connect("operator", 1)
    await operator.send(op="subscribe", topic="/r1/pose")
    await operator.sync()
    await robot.send(op="publish", topic="pose", msg=POSE)
    assert await operator.receive() == {"op": "publish", "topic": "/r1/pose", "msg": POSE}


async def test_a_command_from_the_other_process_reaches_the_robot(connect):
    robot, operator = await connect("r1", 0), await connect("operator", 1)
    await robot.send(op="subscribe", topic="goal")
    await robot.sync()
    await operator.send(op="publish", topic="/r1/goal", msg=POSE)
    assert (await robot.receive())["msg"] == POSE


async def test_a_service_advertised_on_one_process_answers_calls_from_the_other(connect):
    robot, operator = await connect("r1", 0), await connect("operator", 1)
    await robot.send(op="advertise_service", service="dock", type="std_srvs/SetBool")
    await robot.sync()
    await operator.send(op="call_service", id="mine", service="/r1/dock", args={"data": True})
    request = await robot.receive()
    assert request["id"] == "service_request:dock:1"
    await robot.send(
        op="service_response", service="dock", id=request["id"], values={"ok": 1}, result=True
    )
    response = await operator.receive()
    assert response["id"] == "mine"
    assert response["values"] == {"ok": 1}


async def test_an_action_goal_crosses_processes_with_feedback(connect):
    robot, operator = await connect("r1", 0), await connect("operator", 1)
    await robot.send(op="advertise_action", action="navigate", type="a/B")
    await robot.sync()
    await operator.send(
        op="send_action_goal",
        id="g",
        action="/r1/navigate",
        action_type="a/B",
        args={},
        feedback=True,
    )
    goal = await robot.receive()
    await robot.send(op="action_feedback", action="navigate", id=goal["id"], values={"left": 1})
    await robot.send(
        op="action_result", action="navigate", id=goal["id"], values={}, status=4, result=True
    )
    feedback, result = await operator.receive(), await operator.receive()
    assert (feedback["op"], feedback["id"], feedback["values"]) == (
        "action_feedback",
        "g",
        {"left": 1},
    )
    assert (result["op"], result["id"], result["status"]) == ("action_result", "g", 4)


async def test_rosapi_lists_topics_published_on_the_other_process(connect):
    robot, viewer = await connect("r1", 0), await connect("viewer", 1)
    await robot.send(op="advertise", topic="battery", type="sensor_msgs/BatteryState")
    await robot.sync()
    listed = (await viewer.call("/rosapi/topics"))["values"]
    assert "/r1/battery" in listed["topics"]
    nodes = (await viewer.call("/rosapi/nodes"))["values"]["nodes"]
    assert "/r1" in nodes


async def test_a_latched_message_is_replayed_on_the_other_process(connect):
    robot = await connect("r1", 0)
    await robot.send(op="publish", topic="map_id", msg={"data": "boccioni_1/Hall"})
    await robot.sync()
    viewer = await connect("viewer", 1)
    deadline = time.monotonic() + WAIT
    while True:  # the latched message reaches Redis through the relay's send queue
        await viewer.send(op="subscribe", topic="/r1/map_id")
        try:
            frame = await viewer.receive(wait=0.5)
            break
        except TimeoutError:
            await viewer.send(op="unsubscribe", topic="/r1/map_id")
            assert time.monotonic() < deadline, "the latched message never arrived"
    assert frame["msg"] == {"data": "boccioni_1/Hall"}


async def test_params_are_shared(connect):
    robot, viewer = await connect("r1", 0), await connect("viewer", 1)
    await robot.call("/rosapi/set_param", {"name": "max_speed", "value": "0.7"})
    got = await viewer.call("/rosapi/get_param", {"name": "/r1/max_speed"})
    assert got["values"]["value"] == "0.7"


async def test_a_robots_params_go_with_its_connection_on_every_process(connect):
    robot, viewer = await connect("r1", 0), await connect("viewer", 1)
    await robot.call("/rosapi/set_param", {"name": "max_speed", "value": "0.7"})
    await robot.socket.close()
    deadline = time.monotonic() + WAIT
    while (await viewer.call("/rosapi/get_param", {"name": "/r1/max_speed"}))["values"][
        "successful"
    ]:
        assert time.monotonic() < deadline, "the parameter outlived its connection"
        await asyncio.sleep(0.05)


async def test_one_teleop_lock_across_processes_and_the_watchdog_stops_the_robot(connect):
    robot = await connect("r1", 0)
    first, second = await connect("operator", 1), await connect("operator2", 0)
    await robot.send(op="subscribe", topic="cmd_vel")
    await robot.sync()
    lock = {"robot": "r1", "action": "acquire"}
    assert (await first.call("/cloudnav/teleop_lock", lock))["values"]["success"] is True
    refused = (await second.call("/cloudnav/teleop_lock", lock))["values"]
    assert refused["success"] is False
    assert refused["holder"] == "user:operator"
    await first.send(op="publish", topic="/r1/cmd_vel", msg=GO)
    assert (await robot.receive())["msg"] == GO
    assert (await robot.receive(wait=3.0))["msg"] == ZERO


LULL = 7.0  # longer than redis-py's 5 s socket timeout and channels_redis' 5 s blocking pop


async def test_traffic_still_crosses_after_a_lull_longer_than_redis_timeouts(connect):
    robot, operator = await connect("r1", 0), await connect("operator", 1)
    await operator.send(op="subscribe", topic="/r1/pose")
    await robot.send(op="advertise_service", service="dock", type="std_srvs/SetBool")
    await operator.sync()
    await robot.sync()
    await asyncio.sleep(LULL)  # the lull itself is what is tested: no traffic at all
    await robot.send(op="publish", topic="pose", msg=POSE)
    assert (await operator.receive())["msg"] == POSE
    await operator.send(op="call_service", id="after", service="/r1/dock", args={"data": True})
    assert (await robot.receive())["id"] == "service_request:dock:1"


async def test_a_subscription_made_before_the_robot_connects_gets_every_pose(connect):
    operator = await connect("operator", 1)
    await operator.send(op="subscribe", topic="/r1/pose")
    await operator.sync()
    robot = await connect("r1", 0)
    await robot.send(op="advertise", topic="pose", type="geometry_msgs/PoseStamped")
    await publish_poses(robot, range(30))
    assert await operator.poses(30) == list(range(30))


async def test_a_robot_that_reconnects_to_another_process_is_seen_again(connect):
    operator = await connect("operator", 1)
    await operator.send(op="subscribe", topic="/r1/pose")
    await operator.sync()
    for place, seqs in ((0, range(0, 3)), (1, range(3, 6)), (0, range(6, 9))):
        robot = await connect("r1", place)
        await publish_poses(robot, seqs)
        assert await operator.poses(3) == list(seqs)
        await robot.socket.close()


async def test_operators_resume_within_a_second_when_the_robots_process_restarts(cluster, connect):
    operator = await connect("operator", 1)
    await operator.send(op="subscribe", topic="/r1/pose")
    await operator.sync()
    robot = await connect("r1", 0)
    await publish_poses(robot, [0])
    assert await operator.poses(1) == [0]
    cluster.replace(0)  # killed with robot still connected, and started again
    robot = await connect("r1", 0)
    await robot.sync()
    await robot.send(op="publish", topic="pose", msg=pose(1))
    assert await operator.poses(1, wait=1.0) == [1]  # no resubscription


async def test_a_restarted_redis_is_filled_again_from_the_live_connections(
    scaled_servers, private_redis
):
    cluster = scaled_servers(2, env={"REDIS_URL": private_redis.url})
    robot = Client(await websockets.connect(cluster.servers[0].rosbridge_url(cluster.tokens["r1"])))
    viewer = Client(
        await websockets.connect(cluster.servers[1].rosbridge_url(cluster.tokens["r2"]))
    )
    await viewer.send(op="subscribe", topic="/r1/pose")
    await robot.send(op="publish", topic="map_id", msg={"data": "boccioni_1/Hall"})
    await robot.send(op="advertise", topic="battery", type="sensor_msgs/BatteryState")
    await viewer.sync()
    await robot.sync()
    private_redis.restart(down=2.0)
    deadline = time.monotonic() + 20.0  # a heartbeat (5 s) finds Redis empty and refills it
    while True:  # calls made while Redis is away are answered, and fail
        listed = await viewer.call("/rosapi/topics")
        if listed["result"] and "/r1/battery" in listed["values"]["topics"]:
            break
        assert time.monotonic() < deadline, "the robot's topics never came back"
        await asyncio.sleep(0.2)
    await viewer.send(op="subscribe", topic="/r1/map_id")
    assert (await viewer.receive())["msg"] == {"data": "boccioni_1/Hall"}
    await robot.send(op="publish", topic="pose", msg=pose(7))
    assert await viewer.poses(1) == [7]
    await robot.socket.close()
    await viewer.socket.close()
