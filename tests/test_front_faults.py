"""Faults behind the front: three daphne processes behind a real nginx, one killed (-9)
while a robot and operators are connected through it.

Placement: nginx spreads WebSockets by ``least_conn``, so each long-lived socket opened in
turn lands on a process holding none; the tests check where each landed (the front names the
process in ``UPSTREAM_HEADER``) rather than assume it.
"""

from __future__ import annotations

import asyncio
import contextlib
import itertools
import time
from collections.abc import AsyncIterator
from typing import Any

import pytest
import websockets

from robots.agent.client import RosbridgeClient
from tests.fixtures_live import Front, RosClient, SocketCommunicator, until

pytestmark = [pytest.mark.scaled, pytest.mark.slow]

POSE: dict[str, Any] = {
    "header": {"frame_id": "boccioni_1/Hall"},
    "pose": {"position": {"x": 1, "y": 0.75}},
}
GO = {"linear": {"x": 0.3, "y": 0.0, "z": 0.0}, "angular": {"x": 0.0, "y": 0.0, "z": 0.0}}
SEEN_AGAIN = 5.0  # the bound: operators see the robot again within 5 s of the crash
TELEOP_TTL = 5.0  # CLOUDNAV_TELEOP_LOCK_TTL's default
STARTUP = 30.0  # a handshake through the front on a loaded 2-core machine


@pytest.fixture
def front(scaled_servers, nginx_front) -> Front:
    return nginx_front(scaled_servers(3))


@contextlib.asynccontextmanager
async def running(robot: RosbridgeClient) -> AsyncIterator[RosbridgeClient]:
    """Run the robot's client (reconnecting with its own back-off) until the block ends."""
    task = asyncio.create_task(robot.run())
    try:
        async with asyncio.timeout(STARTUP):
            await robot.wait_connected()
        yield robot
    finally:
        await robot.close()
        await asyncio.wait_for(task, STARTUP)


async def operator_through(front: Front, who: str) -> tuple[RosClient, int]:
    """A browser session's rosbridge socket through the front, and the process it reached."""
    socket = await websockets.connect(
        front.server.rosbridge_url(),
        additional_headers={"Cookie": front.cluster.cookies[who], "Origin": front.server.url},
        open_timeout=STARTUP,
    )
    assert socket.response is not None  # set once the handshake succeeded
    return RosClient(SocketCommunicator(socket)), front.process_of(socket.response.headers)


async def publish_poses(robot: RosbridgeClient, published: list[int]) -> None:
    """Publish a pose every 0.1 s (a robot's 10 Hz); note the numbers that went out."""
    for seq in itertools.count():
        if await robot.publish("pose", {**POSE, "header": {**POSE["header"], "seq": seq}}):
            published.append(seq)
        await asyncio.sleep(0.1)


async def test_a_robot_whose_process_is_killed_is_seen_again_through_the_front(front):
    robot = RosbridgeClient(front.server.rosbridge_url(), front.cluster.tokens["r1"], seed=1)
    robot.advertise("pose", "geometry_msgs/PoseStamped")
    async with running(robot):
        robots_process = front.process_of(robot.response_headers)
        operator, operators_process = await operator_through(front, "operator")
        assert operators_process != robots_process, "least_conn put both on one process"
        await operator.send(op="subscribe", topic="/r1/pose")
        await operator.sync()
        published: list[int] = []
        publishing = asyncio.create_task(publish_poses(robot, published))
        await operator.receive_until(lambda f: f.get("topic") == "/r1/pose", wait=STARTUP)

        front.cluster.kill(robots_process)
        killed_at, last_before = time.monotonic(), published[-1]
        await until(lambda: robot.connections == 2, "the robot's reconnection", SEEN_AGAIN)
        assert front.process_of(robot.response_headers) != robots_process
        await operator.receive_until(
            lambda f: f.get("topic") == "/r1/pose" and f["msg"]["header"]["seq"] > last_before,
            wait=SEEN_AGAIN - (time.monotonic() - killed_at),
        )  # on the same socket: no reload, no resubscription
        publishing.cancel()
        await operator.close()


async def test_a_teleop_lock_held_through_a_killed_process_lapses_and_nothing_drives(front):
    commands: list[tuple[float, Any]] = []
    robot = RosbridgeClient(front.server.rosbridge_url(), front.cluster.tokens["r1"], seed=2)
    robot.subscribe(
        "cmd_vel", "geometry_msgs/Twist", lambda m: commands.append((time.monotonic(), m))
    )
    async with running(robot):
        await robot.call_service("/rosapi/get_time")  # its subscription is in place
        holder, holders_process = await operator_through(front, "operator")
        other, others_process = await operator_through(front, "operator2")
        robots_process = front.process_of(robot.response_headers)
        assert len({robots_process, holders_process, others_process}) == 3, "least_conn"
        lock = {"robot": "r1", "action": "acquire"}
        assert (await holder.call("/cloudnav/teleop_lock", lock))["values"]["success"] is True
        await holder.send(op="publish", topic="/r1/cmd_vel", msg=GO)
        await until(lambda: any(m == GO for _, m in commands), "the holder's command")

        front.cluster.kill(holders_process)
        killed_at = time.monotonic()
        refused = (await other.call("/cloudnav/teleop_lock", lock))["values"]
        assert refused["holder"] == "user:operator"  # held through the dead process
        while not (await other.call("/cloudnav/teleop_lock", lock))["values"]["success"]:
            assert time.monotonic() - killed_at < TELEOP_TTL + 5.0, "the lock never lapsed"
            await asyncio.sleep(0.2)
        await other.call("/cloudnav/teleop_lock", {"robot": "r1", "action": "release"})
        await robot.call_service("/rosapi/get_time")  # anything sent to it has arrived
        assert [m for at, m in commands if at > killed_at and moving(m)] == []
        await other.close()


def moving(twist: Any) -> bool:
    return any(value for part in twist.values() for value in part.values())
