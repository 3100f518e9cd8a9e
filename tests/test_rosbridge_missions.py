"""The server runs a mission: sends each goal to its robot and moves on when the robot
says it reached it; a patrol goes round; a failed goal pauses it with the reason."""

from __future__ import annotations

import asyncio
import time

import numpy as np
import pytest
from channels.db import database_sync_to_async

from robots import missions
from robots.models import Mission
from telemetry.missions import GRACE_S
from tests.conftest import make_building, make_robot, make_submap, map_pgm

pytestmark = pytest.mark.django_db(transaction=True)

WAYPOINTS = [{"map": "CorridorA", "x": 1.0, "y": 2.0}, {"map": "CorridorA", "x": 3.0, "y": 1.0}]
GOAL_WAIT = 6.0  # a tick of the runner, and the grace after a goal


@pytest.fixture
def robot(db):
    building = make_building()
    # 5 x 3 m, walled round: waypoints are checked on it
    make_submap(building, code="CorridorA", image=map_pgm(width=100, height=60))
    robot, token = make_robot(name="r1", buildings=[building])
    return building, robot, token


async def next_goal(client) -> dict:
    frame = await client.receive_until(
        lambda f: f.get("op") == "publish" and f.get("topic") in ("goal", "/r1/goal"),
        wait=GOAL_WAIT,
    )
    return frame["msg"]


def status(code: int, text: str = "") -> dict:
    return {
        "header": {"frame_id": ""},
        "status_list": [{"goal_id": {"id": "g"}, "status": code, "text": text}],
    }


async def test_a_patrol_sends_each_goal_when_the_last_was_reached(rosbridge, robot):
    building, record, token = robot
    client = await rosbridge(token=token)
    await client.send(op="subscribe", topic="goal", type="geometry_msgs/PoseStamped")
    mission = await database_sync_to_async(missions.start)(
        building, record, WAYPOINTS, "patrol", "round", "operator"
    )
    first = await next_goal(client)
    assert first["header"]["frame_id"] == "boccioni_1/CorridorA"
    assert first["pose"]["position"]["x"] == pytest.approx(1.0)
    for expected_x in (3.0, 1.0):
        await asyncio.sleep(GRACE_S)  # the robot drives there
        await client.send(op="publish", topic="nav_status", msg=status(1))
        await client.send(op="publish", topic="nav_status", msg=status(3))
        goal = await next_goal(client)
        assert goal["pose"]["position"]["x"] == pytest.approx(expected_x)
    state = await database_sync_to_async(Mission.objects.get)(pk=mission.pk)
    assert (state.index, state.laps, state.state) == (0, 1, "running")


async def test_a_goal_the_robot_aborts_pauses_the_mission_with_its_reason(rosbridge, robot):
    building, record, token = robot
    client = await rosbridge(token=token)
    await client.send(op="subscribe", topic="goal", type="geometry_msgs/PoseStamped")
    mission = await database_sync_to_async(missions.start)(
        building, record, WAYPOINTS, "once", "", "operator"
    )
    await next_goal(client)

    def paused() -> bool:
        return Mission.objects.get(pk=mission.pk).state == "paused"

    deadline = time.monotonic() + GOAL_WAIT
    while not await database_sync_to_async(paused)():
        await client.send(op="publish", topic="nav_status", msg=status(4, "blocked by a box"))
        assert time.monotonic() < deadline
        await asyncio.sleep(0.3)
    note = await database_sync_to_async(lambda: Mission.objects.get(pk=mission.pk).note)()
    assert note == "paused: goal aborted: blocked by a box"


async def test_a_waypoint_walled_in_since_the_mission_began_pauses_it_unsent(rosbridge, robot):
    building, record, token = robot
    mission = await database_sync_to_async(missions.start)(
        building, record, WAYPOINTS, "once", "", "operator"
    )
    await database_sync_to_async(_wall_at_the_first_waypoint)(building)
    client = await rosbridge(token=token)  # its runner starts with the robot
    await client.send(op="subscribe", topic="goal", type="geometry_msgs/PoseStamped")

    def note() -> str:
        found = Mission.objects.get(pk=mission.pk)
        return found.note if found.state == "paused" else ""

    deadline = time.monotonic() + GOAL_WAIT
    while not (paused := await database_sync_to_async(note)()):
        assert time.monotonic() < deadline, "the mission was never paused"
        await asyncio.sleep(0.2)
    assert paused == (
        "paused: The waypoint 1 (1.00, 2.00) is in an obstacle. (boccioni_1/CorridorA)"
    )
    assert await client.quiet()


def _wall_at_the_first_waypoint(building) -> None:
    """A new version of Corridor A with a wall across x = 1 m."""
    image = bytearray(map_pgm(width=100, height=60))
    pixels = np.frombuffer(image, np.uint8, offset=len(image) - 6000).reshape(60, 100)
    pixels[:, 18:22] = 0  # image row 0 is the top; x 0.9 to 1.1 m
    make_submap(building, code="CorridorA", image=bytes(image), replace=True)
