"""Events the server derives as robots connect, publish and leave, kept in the database."""

from __future__ import annotations

import asyncio
import time

import pytest
from channels.db import database_sync_to_async

from telemetry.models import Event
from tests.conftest import make_building, make_robot

pytestmark = pytest.mark.django_db(transaction=True)


@pytest.fixture
def robot(db):
    building = make_building()
    return make_robot(name="r1", buildings=[building])


async def events_of(kind: str, wait: float = 5.0) -> list[Event]:
    """The stored events of ``kind``, once there is one (the log writes every second)."""
    deadline = time.monotonic() + wait

    def rows() -> list[Event]:
        return list(Event.objects.filter(kind=kind).select_related("robot", "building"))

    while not (found := await database_sync_to_async(rows)()):
        assert time.monotonic() < deadline, f"no {kind} event"
        await asyncio.sleep(0.05)
    return found


async def test_connecting_and_leaving_are_kept_with_robot_and_building(rosbridge, robot):
    _, token = robot
    client = await rosbridge(token=token)
    [came] = await events_of("robot_connected")
    assert came.robot is not None
    assert came.building is not None
    assert (came.robot.name, came.building.code, came.alert) == ("r1", "boccioni_1", False)
    await client.close()
    [left] = await events_of("robot_disconnected")
    assert left.alert
    assert left.acknowledged_at is None
    assert left.actor == "robot:r1"


async def test_an_aborted_goal_is_an_open_alert_with_its_reason(rosbridge, robot):
    _, token = robot
    client = await rosbridge(token=token)
    status = {"goal_id": {"id": "g1"}, "status": 4, "text": "no path to the goal"}
    msg = {"header": {"frame_id": ""}, "status_list": [status]}
    await client.send(op="publish", topic="nav_status", msg=msg)
    [aborted] = await events_of("goal_aborted")
    assert aborted.alert
    assert aborted.severity == "error"
    assert aborted.data["reason"] == "no path to the goal"


async def test_a_low_battery_is_an_alert(rosbridge, robot):
    _, token = robot
    client = await rosbridge(token=token)
    await client.send(op="publish", topic="battery", msg={"percentage": 0.12})
    [low] = await events_of("battery_low")
    assert low.alert
    assert low.data["percentage"] == pytest.approx(0.12)
