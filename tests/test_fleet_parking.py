"""The parking rule (issue 28, point 1): a robot that finished its goal where others need
to be (another robot is going there, or a narrow place) is sent to the nearest free
parking spot of its building, and an event says so.

The rules on their own (``maps.domain.reservations``; the width measure has
``tests/test_widths.py``), then robots of the demo building connected to the real ASGI
application reporting their goals' ends as the agent does."""

from __future__ import annotations

import asyncio
import io
import json
import time

import pytest
from channels.db import database_sync_to_async
from django.contrib.auth.models import User
from django.core.management import call_command

from maps.domain.reservations import FleetRule, ParkingPlace, Reservations
from maps.models import Building, ParkingSpot, SubMap
from telemetry.models import Event

RADIUS = 0.25
CORRIDOR = "boccioni_1/CorridorA"
DOORWAY = (17.9, 23.8)  # in the opening from Corridor A to Atrium 1, 1.2 m wide
MIDDLE = (12.0, 23.2)  # Corridor A, 2.4 m wide
NEAR, FAR = ParkingPlace("near", CORRIDOR, 15.0, 22.6), ParkingPlace("far", CORRIDOR, 5.0, 22.6)
SUCCEEDED, ACTIVE = 3, 1


def nowhere_narrow(_map: str, _point: tuple[float, float]) -> bool:
    return False


# ---------------------------------------------------------------- the rules


def test_a_robot_idle_where_another_is_going_is_in_the_way():
    spots = Reservations(RADIUS)
    spots.stand("r1", CORRIDOR, *MIDDLE)
    spots.stand("r2", CORRIDOR, 5.0, 23.2)
    assert spots.in_the_way("r1", nowhere_narrow) == ""
    spots.aim("r2", CORRIDOR, (MIDDLE[0] + 0.3, MIDDLE[1]))
    assert spots.in_the_way("r1", nowhere_narrow) == "r2 is going to where it stands"


def test_a_robot_with_a_goal_is_in_nobodys_way():
    spots = Reservations(RADIUS)
    spots.stand("r1", CORRIDOR, *DOORWAY)
    spots.aim("r1", CORRIDOR, MIDDLE)
    assert spots.in_the_way("r1", lambda _m, _p: True) == ""


def test_a_narrow_place_is_in_the_way():
    spots = Reservations(RADIUS)
    spots.stand("r1", CORRIDOR, *DOORWAY)
    assert "narrow place" in spots.in_the_way("r1", lambda _m, p: p == DOORWAY)


def test_the_nearest_parking_spot_nobody_holds_is_chosen():
    spots = Reservations(RADIUS)
    spots.stand("r1", CORRIDOR, *DOORWAY)
    assert spots.nearest_parking("r1", [FAR, NEAR]) == NEAR
    spots.stand("r2", CORRIDOR, NEAR.x, NEAR.y)
    assert spots.nearest_parking("r1", [FAR, NEAR]) == FAR
    spots.aim("r3", CORRIDOR, (FAR.x, FAR.y))
    spots.stand("r3", CORRIDOR, 0.0, 0.0)
    assert spots.nearest_parking("r1", [FAR, NEAR]) is None


def test_a_spot_in_its_own_sub_map_comes_before_a_nearer_one_elsewhere():
    spots = Reservations(RADIUS)
    spots.stand("r1", CORRIDOR, *DOORWAY)
    atrium = ParkingPlace("atrium", "boccioni_1/Atrium1", 18.5, 23.8)
    assert spots.nearest_parking("r1", [atrium, FAR]) == FAR


# ---------------------------------------------------------------- through rosbridge

live = pytest.mark.django_db(transaction=True)


@pytest.fixture
def demo(tmp_path):
    """The demo building with three robots, a parking spot in Corridor A, and the tokens."""
    tokens = tmp_path / "tokens.json"
    call_command("seed_demo", "--robots", "3", "--tokens-file", str(tokens), stdout=io.StringIO())
    submap = SubMap.objects.get(building__code="boccioni_1", code="CorridorA")
    ParkingSpot.objects.create(
        building=submap.building, submap=submap, name="by the cabinet", x=NEAR.x, y=NEAR.y
    )
    return json.loads(tokens.read_text())


def pose(point: tuple[float, float], map_id: str = CORRIDOR) -> dict:
    return {
        "header": {"frame_id": map_id},
        "pose": {"position": {"x": point[0], "y": point[1], "z": 0.0}, "orientation": {"w": 1.0}},
    }


def status(code: int) -> dict:
    return {"status_list": [{"goal_id": {"id": "goal_1"}, "status": code, "text": ""}]}


async def robot_at(rosbridge, token: str, point: tuple[float, float]):
    """A robot connected, listening to its goals, that said it stands at ``point``."""
    robot = await rosbridge(token=token)
    await robot.send(op="subscribe", topic="goal")
    await robot.send(op="publish", topic="pose", msg=pose(point))
    await robot.sync()
    return robot


async def finish_goal_at(robot, point: tuple[float, float]) -> None:
    """The robot was sent a goal at ``point``, drove there and reports it reached."""
    await robot.send(op="publish", topic="nav_status", msg=status(ACTIVE))
    await robot.send(op="publish", topic="pose", msg=pose(point))
    await asyncio.sleep(1.6)  # the goal's grace (GOAL_GRACE_S): its earlier statuses end nothing
    await robot.send(op="publish", topic="nav_status", msg=status(SUCCEEDED))
    await robot.sync()


async def send_goal(rosbridge, robot: str, point: tuple[float, float]) -> None:
    operator = await rosbridge(
        user=await database_sync_to_async(User.objects.get)(username="operator")
    )
    await operator.send(op="publish", topic=f"/{robot}/goal", msg=pose(point))
    await operator.sync()


def parking_events(robot: str) -> list[str]:
    events = Event.objects.filter(robot__name=robot, kind="goal_sent")
    return [e.message for e in events if "parking spot" in e.message]


async def events_until(robot: str, wait: float = 20.0) -> list[str]:
    deadline = time.monotonic() + wait
    while not (found := await database_sync_to_async(parking_events)(robot)):
        assert time.monotonic() < deadline, "no event says the robot was parked"
        await asyncio.sleep(0.2)
    return found


@live
async def test_a_robot_that_finished_its_goal_in_a_doorway_is_sent_to_park(rosbridge, demo):
    robot = await robot_at(rosbridge, demo["robot_0"], (10.0, 23.2))
    await send_goal(rosbridge, "robot_0", DOORWAY)
    await robot.receive_until(lambda f: f.get("op") == "publish")  # the operator's goal
    await finish_goal_at(robot, DOORWAY)
    parked = await robot.receive_until(lambda f: f.get("op") == "publish", wait=20)
    at = parked["msg"]["pose"]["position"]
    assert (parked["msg"]["header"]["frame_id"], at["x"], at["y"]) == (CORRIDOR, NEAR.x, NEAR.y)
    [said] = await events_until("robot_0")
    assert "sent to parking spot by the cabinet: it stands in a narrow place" in said


@live
async def test_an_idle_robot_where_another_is_sent_makes_way(rosbridge, demo):
    idle = await robot_at(rosbridge, demo["robot_1"], MIDDLE)
    await robot_at(rosbridge, demo["robot_0"], (6.0, 23.2))
    await send_goal(rosbridge, "robot_0", MIDDLE)  # moved off robot_1's spot
    parked = await idle.receive_until(lambda f: f.get("op") == "publish", wait=20)
    at = parked["msg"]["pose"]["position"]
    assert (at["x"], at["y"]) == (NEAR.x, NEAR.y)
    [said] = await events_until("robot_1")
    assert "robot_0 was sent where it stands" in said


@live
async def test_a_robot_that_finished_its_goal_out_of_the_way_stays(rosbridge, demo):
    robot = await robot_at(rosbridge, demo["robot_0"], (10.0, 23.2))
    await send_goal(rosbridge, "robot_0", MIDDLE)
    await robot.receive_until(lambda f: f.get("op") == "publish")
    await finish_goal_at(robot, MIDDLE)
    await asyncio.sleep(4.0)  # past the rule's settling time (SETTLE_S): it looked, and stays
    await robot.sync()
    assert await robot.quiet()
    assert await database_sync_to_async(parking_events)("robot_0") == []


@live
async def test_robots_planning_alone_are_never_parked(rosbridge, demo):
    await database_sync_to_async(Building.objects.filter(code="boccioni_1").update)(
        fleet_rule=FleetRule.OFF.value
    )
    robot = await robot_at(rosbridge, demo["robot_0"], (10.0, 23.2))
    await send_goal(rosbridge, "robot_0", DOORWAY)
    await robot.receive_until(lambda f: f.get("op") == "publish")
    await finish_goal_at(robot, DOORWAY)
    await asyncio.sleep(4.0)  # past the rule's settling time (SETTLE_S)
    assert await robot.quiet()
    assert await database_sync_to_async(parking_events)("robot_0") == []
