"""STOP (``/cloudnav/stop``): one operator halts a robot whatever moves it: a goal sent by
another connection, a mission, another operator's teleop; the robot is told to cancel its
goal and given a zero Twist, its mission pauses, and an event names who stopped it."""

from __future__ import annotations

import asyncio
import time

import pytest
from channels.db import database_sync_to_async

from robots import missions
from robots.models import Mission, Robot
from telemetry.models import Event
from tests.conftest import make_building, make_submap, make_user

pytestmark = pytest.mark.django_db(transaction=True)

STOP = "/cloudnav/stop"
GO = {"linear": {"x": 0.3, "y": 0.0, "z": 0.0}, "angular": {"x": 0.0, "y": 0.0, "z": 0.0}}
ZERO = {"linear": {"x": 0.0, "y": 0.0, "z": 0.0}, "angular": {"x": 0.0, "y": 0.0, "z": 0.0}}
GOAL = {
    "header": {"frame_id": "boccioni_1/CorridorA"},
    "pose": {"position": {"x": 1.0, "y": 0.75, "z": 0.0}, "orientation": {"w": 1.0}},
}


@pytest.fixture
def robot_token(building, token):
    """Robot ``r1``'s token, with its building's CorridorA to check goals against."""
    make_submap(building, code="CorridorA")
    return token


async def robot_serving_cancel(rosbridge, token):
    """The robot's side: it hears cmd_vel and goal, and serves cancel_goal."""
    robot = await rosbridge(token=token)
    await robot.send(op="advertise_service", service="cancel_goal", type="std_srvs/Trigger")
    for topic in ("cmd_vel", "goal"):
        await robot.send(op="subscribe", topic=topic)
    await robot.sync()
    return robot


async def answer_the_cancel(robot) -> dict:
    request = await robot.receive_until(lambda f: f.get("op") == "call_service")
    assert request["service"] in ("cancel_goal", "/r1/cancel_goal")
    await robot.send(
        op="service_response",
        service=request["service"],
        id=request["id"],
        values={"success": True, "message": "cancelled"},
        result=True,
    )
    return request


async def test_stop_cancels_a_goal_another_operator_sent(
    rosbridge, robot_token, operator, second_operator
):
    robot = await robot_serving_cancel(rosbridge, robot_token)
    sender, stopper = await rosbridge(user=second_operator), await rosbridge(user=operator)
    await sender.send(op="publish", topic="/r1/goal", msg=GOAL)
    await robot.receive_until(lambda f: f.get("topic") in ("goal", "/r1/goal"))
    await stopper.send(op="call_service", id="stop", service=STOP, args={"robot": "r1"})
    zero = await robot.receive_until(lambda f: f.get("topic") in ("cmd_vel", "/r1/cmd_vel"))
    assert zero["msg"] == ZERO
    await answer_the_cancel(robot)
    reply = await stopper.receive_until(lambda f: f.get("id") == "stop")
    assert reply["result"] is True
    assert reply["values"]["goal"] == "cancelled"
    assert "goal: cancelled" in reply["values"]["message"]


async def test_stop_pauses_the_robots_mission_and_says_so_in_the_events(
    rosbridge, robot_token, building, operator
):
    robot = await robot_serving_cancel(rosbridge, robot_token)
    record = await database_sync_to_async(Robot.objects.get)(name="r1")
    mission = await database_sync_to_async(missions.start)(
        building, record, [{"map": "CorridorA", "x": 1.0, "y": 0.75}], "patrol", "round", "admin"
    )
    stopper = await rosbridge(user=operator)
    await stopper.send(op="call_service", id="stop", service=STOP, args={"robot": "r1"})
    await answer_the_cancel(robot)
    reply = await stopper.receive_until(lambda f: f.get("id") == "stop")
    assert reply["values"]["missions"] == ["round"]
    paused = await database_sync_to_async(Mission.objects.get)(pk=mission.pk)
    assert (paused.state, paused.note) == ("paused", "paused: r1 stopped by user:operator")
    event = await _stop_event()
    assert event.actor == "user:operator"
    assert "r1 stopped by user:operator" in event.message
    assert "mission paused: round" in event.message


async def _stop_event() -> Event:
    deadline = time.monotonic() + 10
    while True:
        found = await database_sync_to_async(
            lambda: Event.objects.filter(kind="robot_stopped").first()
        )()
        if found is not None:
            return found
        assert time.monotonic() < deadline, "no robot_stopped event was written"
        await asyncio.sleep(0.1)


async def test_stop_withdraws_another_operators_teleop_lock(
    rosbridge, robot_token, operator, second_operator
):
    robot = await robot_serving_cancel(rosbridge, robot_token)
    driver, stopper = await rosbridge(user=second_operator), await rosbridge(user=operator)
    lock = await driver.call("/cloudnav/teleop_lock", {"robot": "r1", "action": "acquire"})
    assert lock["values"]["success"] is True
    await driver.send(op="publish", topic="/r1/cmd_vel", msg=GO)
    assert (await robot.receive_until(lambda f: f.get("op") == "publish"))["msg"] == GO
    await stopper.send(op="call_service", id="stop", service=STOP, args={"robot": "r1"})
    await answer_the_cancel(robot)
    reply = await stopper.receive_until(lambda f: f.get("id") == "stop")
    assert reply["values"]["teleop"] == "user:operator2"
    await driver.send(op="publish", topic="/r1/cmd_vel", msg=GO)
    await driver.sync()
    while not await robot.quiet():
        assert (await robot.receive())["msg"] == ZERO  # never GO again


async def test_stop_answers_when_the_robot_is_not_connected(rosbridge, robot_token, operator):
    stopper = await rosbridge(user=operator)
    reply = await stopper.call(STOP, {"robot": "r1"})
    assert reply["result"] is True
    assert reply["values"]["goal"] == "the robot is not connected"


async def test_a_viewer_cannot_stop_a_robot(rosbridge, robot_token, viewer):
    reply = await (await rosbridge(user=viewer)).call(STOP, {"robot": "r1"})
    assert reply["result"] is False


@pytest.fixture
def stranger(db):
    """An operator of another building."""
    user = make_user("operator9", "operator")
    make_building(code="other_1", members=[user])
    return user


async def test_it_rejects_outsider(rosbridge, robot_token, stranger):
    reply = await (await rosbridge(user=stranger)).call(STOP, {"robot": "r1"})
    assert reply["result"] is False


@pytest.mark.parametrize("name", ["", "/r1", 42, None, "r1/../r2"])
async def test_stop_refuses_what_is_not_a_robots_name(rosbridge, robot_token, operator, name):
    reply = await (await rosbridge(user=operator)).call(STOP, {"robot": name})
    assert reply["result"] is False
    assert "'robot' must be a robot's name" in str(reply["values"])


async def test_the_operator_who_stops_keeps_the_lock_they_hold(rosbridge, robot_token, operator):
    robot = await robot_serving_cancel(rosbridge, robot_token)
    driver = await rosbridge(user=operator)
    await driver.call("/cloudnav/teleop_lock", {"robot": "r1", "action": "acquire"})
    await driver.send(op="call_service", id="stop", service=STOP, args={"robot": "r1"})
    await answer_the_cancel(robot)
    reply = await driver.receive_until(lambda f: f.get("id") == "stop")
    assert reply["values"]["teleop"] == ""
    await driver.send(op="publish", topic="/r1/cmd_vel", msg=GO)
    assert (await robot.receive_until(lambda f: f["msg"] != ZERO))["msg"] == GO
