"""Destinations are reserved (issue 28, point 1): a goal or mission waypoint whose spot
another robot holds, standing there or going there, is refused with the reason or moved to
the nearest free spot by the building's fleet rule, and the operator is told plainly.

The rules on their own (``maps.domain.reservations``), then two robots of the demo building
connected to the real ASGI application, one operator sending them goals and missions."""

from __future__ import annotations

import asyncio
import io
import json
import math
import time

import pytest
from channels.db import database_sync_to_async
from django.contrib.auth.models import User
from django.core.management import call_command
from rest_framework.test import APIClient

from maps.domain.reservations import FleetRule, Reservations
from maps.models import Building
from robots import missions
from robots.models import Mission, Robot

RADIUS = 0.25  # the demo robots' planning radius (body and margin)
ATRIUM = "boccioni_1/Atrium1"
SPOT = (20.0, 23.2)  # between Atrium 1's door and its central pillar


def anywhere(_point: tuple[float, float]) -> bool:
    return True


# ---------------------------------------------------------------- the rules


def test_a_spot_nobody_holds_is_taken_as_asked():
    spots = Reservations(RADIUS)
    spots.stand("r1", "b/m", 0.0, 0.0)
    placed = spots.place("b/m", (0.6, 0.0), "r2", FleetRule.REFUSE, anywhere)
    assert (placed.point, placed.refusal, placed.message) == ((0.6, 0.0), "", "")


def test_a_robot_never_holds_a_spot_against_itself():
    spots = Reservations(RADIUS)
    spots.stand("r1", "b/m", 0.0, 0.0)
    assert spots.place("b/m", (0.0, 0.0), "r1", FleetRule.REFUSE, anywhere).refusal == ""


def test_the_refusing_rule_names_the_robot_standing_there():
    spots = Reservations(RADIUS)
    spots.stand("r1", "b/m", 1.0, 1.0)
    placed = spots.place("b/m", (1.2, 1.0), "r2", FleetRule.REFUSE, anywhere)
    assert placed.refusal.startswith("The goal (1.20, 1.00) is held: r1 stands at (1.00, 1.00)")


def test_the_moving_rule_takes_the_nearest_spot_clear_of_every_robot_and_wall():
    spots = Reservations(RADIUS)
    spots.stand("r1", "b/m", 0.0, 0.0)
    east_is_wall = lambda p: p[0] <= 0.0  # noqa: E731
    placed = spots.place("b/m", (0.0, 0.0), "r2", FleetRule.MOVE, east_is_wall)
    assert placed.moved_from == (0.0, 0.0)
    assert 2 * RADIUS <= math.dist(placed.point, (0.0, 0.0)) <= 2 * RADIUS + 0.11
    assert placed.point[0] <= 0.0
    assert placed.message.startswith("Moved to the nearest free spot (")
    assert "r1 stands at (0.00, 0.00)" in placed.message


def test_a_spot_with_no_free_one_near_is_refused_even_by_the_moving_rule():
    spots = Reservations(RADIUS)
    spots.stand("r1", "b/m", 0.0, 0.0)
    placed = spots.place("b/m", (0.0, 0.0), "r2", FleetRule.MOVE, lambda _p: False)
    assert "no free spot is within 2.0 m" in placed.refusal


def test_an_active_goal_holds_its_spot_until_the_robot_says_it_is_over():
    now = [0.0]
    spots = Reservations(RADIUS, clock=lambda: now[0])
    spots.stand("r1", "b/m", 5.0, 5.0)
    spots.aim("r1", "b/m@v3", (0.0, 0.0))
    held = spots.holder("b/m", (0.1, 0.0), "r2")
    assert held is not None
    assert held.describe() == "r1 is going to (0.00, 0.00)"
    spots.goal_over("r1")  # the status of the goal before: within the grace
    assert spots.holder("b/m", (0.1, 0.0), "r2") is not None
    now[0] = 2.0
    spots.goal_over("r1")
    assert spots.holder("b/m", (0.1, 0.0), "r2") is None


def test_spots_are_per_sub_map_and_a_robot_that_left_holds_none():
    spots = Reservations(RADIUS)
    spots.stand("r1", "b/m", 0.0, 0.0)
    assert spots.holder("b/other", (0.0, 0.0), "r2") is None
    spots.aim("r1", "b/m", (3.0, 3.0))
    spots.leave("r1")
    assert spots.holder("b/m", (0.0, 0.0), "r2") is None
    assert spots.holder("b/m", (3.0, 3.0), "r2") is None


def test_a_goal_sent_to_a_robot_never_heard_here_holds_nothing():
    spots = Reservations(RADIUS)
    spots.aim("ghost", "b/m", (0.0, 0.0))
    assert spots.holder("b/m", (0.0, 0.0), "r2") is None


# ---------------------------------------------------------------- through rosbridge

live = pytest.mark.django_db(transaction=True)


@pytest.fixture
def demo(tmp_path):
    """The demo building with two robots, its operator, and the robots' tokens."""
    tokens = tmp_path / "tokens.json"
    call_command("seed_demo", "--robots", "2", "--tokens-file", str(tokens), stdout=io.StringIO())
    return User.objects.get(username="operator"), json.loads(tokens.read_text())


def goal(x: float, y: float, map_id: str = ATRIUM) -> dict:
    return {
        "header": {"frame_id": map_id},
        "pose": {"position": {"x": x, "y": y, "z": 0.0}, "orientation": {"w": 1.0}},
    }


async def robot_at(rosbridge, token: str, point: tuple[float, float]):
    """A robot connected, listening to its goals, that said it stands at ``point``."""
    robot = await rosbridge(token=token)
    await robot.send(op="subscribe", topic="goal")
    await robot.send(op="publish", topic="pose", msg=goal(*point))
    await robot.sync()
    return robot


async def operator_page(rosbridge, operator):
    page = await rosbridge(user=operator)
    await page.send(op="set_level", level="warning")
    return page


def set_rule(rule: FleetRule) -> None:
    Building.objects.filter(code="boccioni_1").update(fleet_rule=rule.value)


@live
async def test_a_goal_where_another_robot_stands_is_moved_and_the_operator_told(rosbridge, demo):
    operator, tokens = demo
    robot_0 = await robot_at(rosbridge, tokens["robot_0"], (21.0, 24.0))
    await robot_at(rosbridge, tokens["robot_1"], SPOT)
    page = await operator_page(rosbridge, operator)
    await page.send(op="publish", topic="/robot_0/goal", msg=goal(*SPOT))
    told = await page.receive_until(lambda f: f.get("op") == "status")
    assert told["level"] == "warning"
    assert "Moved to the nearest free spot" in told["msg"]
    assert "robot_1 stands at (20.00, 23.20)" in told["msg"]
    sent = await robot_0.receive_until(lambda f: f.get("op") == "publish")
    at = sent["msg"]["pose"]["position"]
    assert 2 * RADIUS <= math.dist((at["x"], at["y"]), SPOT) <= 2 * RADIUS + 0.2
    assert sent["msg"]["header"]["frame_id"] == ATRIUM


@live
async def test_two_robots_sent_to_one_spot_by_a_refusing_building(rosbridge, demo):
    operator, tokens = demo
    await database_sync_to_async(set_rule)(FleetRule.REFUSE)
    robot_0 = await robot_at(rosbridge, tokens["robot_0"], (21.0, 24.0))
    robot_1 = await robot_at(rosbridge, tokens["robot_1"], (19.0, 25.0))
    page = await operator_page(rosbridge, operator)
    await page.send(op="publish", topic="/robot_0/goal", msg=goal(*SPOT))
    await robot_0.receive_until(lambda f: f.get("op") == "publish")
    await page.send(op="publish", topic="/robot_1/goal", msg=goal(SPOT[0] + 0.2, SPOT[1]))
    refusal = await page.receive_until(lambda f: f.get("op") == "status")
    assert refusal["level"] == "error"
    assert "robot_0 is going to (20.00, 23.20)" in refusal["msg"]
    assert "this building refuses such goals" in refusal["msg"]
    assert await robot_1.quiet()


@live
async def test_the_page_is_told_where_a_goal_would_go_before_it_sends(rosbridge, demo):
    operator, tokens = demo
    await robot_at(rosbridge, tokens["robot_1"], SPOT)
    page = await operator_page(rosbridge, operator)
    asked = {"map_id": ATRIUM, "x": SPOT[0], "y": SPOT[1], "robot": "robot_0"}
    answer = (await page.call("/cloudnav/check_pose", asked))["values"]
    assert answer["success"] is True
    assert "robot_1 stands at" in answer["message"]
    assert math.dist((answer["x"], answer["y"]), SPOT) >= 2 * RADIUS
    await database_sync_to_async(set_rule)(FleetRule.REFUSE)
    deadline = time.monotonic() + 20  # the building's rule is read again every 2 s (FRESH_S)
    while (answer := (await page.call("/cloudnav/check_pose", asked, id="again"))["values"])[
        "success"
    ]:
        assert time.monotonic() < deadline, "the new rule was never read"
        await asyncio.sleep(0.2)
    assert "robot_1 stands at" in answer["message"]


def start_mission(robot: str, point: tuple[float, float]) -> Mission:
    building = Building.objects.get(code="boccioni_1")
    waypoints = [{"map": "Atrium1", "x": point[0], "y": point[1], "yaw": 0.0}]
    return missions.start(
        building, Robot.objects.get(name=robot), waypoints, "once", "to the atrium", "operator"
    )


def mission_state(pk: int) -> tuple[str, str]:
    mission = Mission.objects.get(pk=pk)
    return mission.state, mission.note


@live
async def test_a_mission_waypoint_held_by_a_robot_pauses_its_mission_with_the_reason(
    rosbridge, demo
):
    _, tokens = demo
    await database_sync_to_async(set_rule)(FleetRule.REFUSE)
    await robot_at(rosbridge, tokens["robot_1"], SPOT)
    robot_0 = await robot_at(rosbridge, tokens["robot_0"], (21.0, 24.0))
    mission = await database_sync_to_async(start_mission)("robot_0", SPOT)
    deadline = time.monotonic() + 20
    while (state := await database_sync_to_async(mission_state)(mission.pk))[0] == "running":
        assert time.monotonic() < deadline, "the mission never paused"
        await asyncio.sleep(0.1)
    assert state[0] == "paused"
    assert "robot_1 stands at (20.00, 23.20)" in state[1]
    assert await robot_0.quiet()


@live
async def test_a_mission_waypoint_held_by_a_robot_is_moved_by_the_moving_rule(rosbridge, demo):
    _, tokens = demo
    await robot_at(rosbridge, tokens["robot_1"], SPOT)
    robot_0 = await robot_at(rosbridge, tokens["robot_0"], (21.0, 24.0))
    await database_sync_to_async(start_mission)("robot_0", SPOT)
    sent = await robot_0.receive_until(lambda f: f.get("op") == "publish", wait=20)
    at = sent["msg"]["pose"]["position"]
    assert math.dist((at["x"], at["y"]), SPOT) >= 2 * RADIUS


@live
def test_a_building_admin_sets_the_fleet_rule_and_nothing_else_is_one(demo):
    client = APIClient()
    client.force_authenticate(User.objects.get(username="admin"))
    url = "/api/buildings/boccioni_1/"
    answer = client.patch(url, {"fleet_rule": "sideways"}, format="json")
    assert answer.status_code == 400
    assert "fleet_rule" in answer.json()
    answer = client.patch(url, {"fleet_rule": "refuse"}, format="json")
    assert (answer.status_code, answer.json()["fleet_rule"]) == (200, "refuse")
    client.force_authenticate(User.objects.get(username="operator"))
    assert client.patch(url, {"fleet_rule": "move"}, format="json").status_code == 403
