"""A mission waypoint not reached within its time limit is skipped or pauses the mission,
as the mission says, with a ``waypoint_timed_out`` event (issue 28, point 3): a robot of
the demo building connected to the real ASGI application takes its goal and never gets
there."""

from __future__ import annotations

import asyncio
import io
import json
import time
from collections.abc import Callable

import pytest
from channels.db import database_sync_to_async
from django.contrib.auth.models import User
from django.core.management import call_command
from rest_framework.test import APIClient

from maps.models import Building
from robots import missions
from robots.models import Mission, Robot
from telemetry.models import Event

pytestmark = pytest.mark.django_db(transaction=True)

WAYPOINTS = [
    {"map": "Atrium1", "x": 20.0, "y": 23.2, "yaw": 0.0},
    {"map": "Atrium1", "x": 21.0, "y": 24.0, "yaw": 0.0},
]


@pytest.fixture
def token(tmp_path) -> str:
    tokens = tmp_path / "tokens.json"
    call_command("seed_demo", "--robots", "1", "--tokens-file", str(tokens), stdout=io.StringIO())
    return json.loads(tokens.read_text())["robot_0"]


def start(on_timeout: str) -> Mission:
    return missions.start(
        Building.objects.get(code="boccioni_1"),
        Robot.objects.get(name="robot_0"),
        WAYPOINTS,
        "once",
        "round the atrium",
        "operator",
        time_limit=1.5,
        on_timeout=on_timeout,
    )


def mission_of(pk: int) -> Mission:
    return Mission.objects.get(pk=pk)


def timed_out_events() -> list[Event]:
    return list(Event.objects.filter(kind="waypoint_timed_out", robot__name="robot_0"))


async def eventually(check: Callable[[], bool], wait: float = 30.0) -> None:
    deadline = time.monotonic() + wait
    while not await database_sync_to_async(check)():
        assert time.monotonic() < deadline, "the condition never held"
        await asyncio.sleep(0.1)


async def robot_taking_goals(rosbridge, token: str):
    robot = await rosbridge(token=token)
    await robot.send(op="subscribe", topic="goal")
    await robot.sync()
    return robot


def position(frame: dict) -> tuple[float, float]:
    at = frame["msg"]["pose"]["position"]
    return at["x"], at["y"]


async def test_a_waypoint_not_reached_in_time_is_skipped_when_the_mission_says_so(rosbridge, token):
    robot = await robot_taking_goals(rosbridge, token)
    mission = await database_sync_to_async(start)("skip")
    first = await robot.receive_until(lambda f: f.get("op") == "publish", wait=20)
    assert position(first) == pytest.approx((20.0, 23.2))
    second = await robot.receive_until(lambda f: f.get("op") == "publish", wait=30)
    assert position(second) == pytest.approx((21.0, 24.0))
    found = await database_sync_to_async(mission_of)(mission.pk)
    assert (found.state, found.index) == ("running", 1)
    assert found.note == "waypoint 1 not reached within 1.5 s: skipped"
    await eventually(lambda: bool(timed_out_events()))
    [event] = await database_sync_to_async(timed_out_events)()
    assert "did not reach its waypoint in boccioni_1/Atrium1 (20.00, 23.20)" in event.message
    assert event.data["then"] == "skipped, on to the next waypoint"


async def test_a_waypoint_not_reached_in_time_pauses_the_mission_when_it_says_so(rosbridge, token):
    robot = await robot_taking_goals(rosbridge, token)
    mission = await database_sync_to_async(start)("pause")
    await robot.receive_until(lambda f: f.get("op") == "publish", wait=20)
    await eventually(lambda: mission_of(mission.pk).state == "paused")
    found = await database_sync_to_async(mission_of)(mission.pk)
    assert found.note == "paused: waypoint 1 not reached within 1.5 s"
    await eventually(lambda: bool(timed_out_events()))
    [event] = await database_sync_to_async(timed_out_events)()
    assert event.data["then"].startswith("mission paused, the robot halted")
    assert await robot.quiet()  # no next waypoint


def test_the_api_refuses_a_negative_time_limit_or_an_unknown_rule(token):
    client = APIClient()
    client.force_authenticate(User.objects.get(username="operator"))
    asked = {"building": "boccioni_1", "robot": "robot_0", "waypoints": WAYPOINTS}
    answer = client.post("/api/missions/", {**asked, "time_limit": -1}, format="json")
    assert answer.status_code == 400
    assert "time_limit" in answer.json()
    answer = client.post("/api/missions/", {**asked, "on_timeout": "wait"}, format="json")
    assert answer.status_code == 400
    assert "on_timeout" in answer.json()
    answer = client.post("/api/missions/", {**asked, "on_timeout": "skip"}, format="json")
    assert answer.status_code == 201
    assert (answer.json()["time_limit"], answer.json()["on_timeout"]) == (300.0, "skip")


def clock_at(seconds: int) -> dict:
    """A goal status array (none active) stamped ``seconds`` of the robot's clock."""
    return {"header": {"stamp": {"sec": seconds, "nanosec": 0}}, "status_list": []}


async def test_a_time_limit_runs_on_the_robots_own_clock(rosbridge, token):
    # A simulated robot whose clock stands still (a paused simulation) is not timed out
    # by the server's seconds; once its own clock passes the limit, the waypoint is.
    robot = await robot_taking_goals(rosbridge, token)
    await robot.send(op="publish", topic="nav_status", msg=clock_at(100))
    mission = await database_sync_to_async(start)("skip")
    await robot.receive_until(lambda f: f.get("op") == "publish", wait=20)
    standing_still = time.monotonic() + 4.0  # well past the 1.5 s limit on the server's clock
    while time.monotonic() < standing_still:
        await robot.send(op="publish", topic="nav_status", msg=clock_at(101))
        await asyncio.sleep(0.2)
    found = await database_sync_to_async(mission_of)(mission.pk)
    assert (found.state, found.index) == ("running", 0)
    await robot.send(op="publish", topic="nav_status", msg=clock_at(102))
    second = await robot.receive_until(lambda f: f.get("op") == "publish", wait=30)
    assert position(second) == pytest.approx((21.0, 24.0))
    found = await database_sync_to_async(mission_of)(mission.pk)
    assert found.note == "waypoint 1 not reached within 1.5 s: skipped"
