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


def whereabouts(state: str, map_id: str = "", source: str = "") -> dict:
    values = {"state": state, "map_id": map_id, "source": source}
    return {
        "level": 0 if state == "localised" else 1,
        "name": "localisation",
        "message": state,
        "hardware_id": "",
        "values": [{"key": key, "value": value} for key, value in values.items()],
    }


async def open_alerts(kind: str) -> list[Event]:
    def rows() -> list[Event]:
        return list(Event.objects.filter(kind=kind, alert=True, cleared_at__isnull=True))

    return await database_sync_to_async(rows)()


async def test_a_robot_lost_before_its_first_tag_is_starting_and_raises_nothing(rosbridge, robot):
    _, token = robot
    client = await rosbridge(token=token)
    await client.send(op="publish", topic="localisation", msg=whereabouts("lost"))
    corridor = "boccioni_1/CorridorA"
    await client.send(
        op="publish", topic="localisation", msg=whereabouts("entering", corridor, "tag 0")
    )
    await client.send(
        op="publish", topic="localisation", msg=whereabouts("localised", corridor, "tag 0")
    )
    await events_of("tag_read")
    await client.close()
    await events_of("robot_disconnected")
    assert await open_alerts("robot_lost") == []


async def test_an_alert_clears_itself_when_its_condition_ends_and_stays_in_the_events(
    rosbridge, robot
):
    _, token = robot
    client = await rosbridge(token=token)
    corridor = "boccioni_1/CorridorA"
    await client.send(
        op="publish", topic="localisation", msg=whereabouts("localised", corridor, "tag 0")
    )
    await client.send(op="publish", topic="localisation", msg=whereabouts("lost"))
    [lost] = await events_of("robot_lost")
    assert lost.cleared_at is None
    await client.send(
        op="publish", topic="localisation", msg=whereabouts("localised", corridor, "tag 0")
    )
    [clearing] = await events_of("alert_cleared")
    assert (clearing.alert, clearing.data) == (False, {"alert": "robot_lost"})
    [kept] = await events_of("robot_lost")
    assert kept.cleared_at == clearing.time
    assert await open_alerts("robot_lost") == []


async def test_the_same_condition_never_raises_twice_across_reconnections(rosbridge, robot):
    _, token = robot
    for _ in range(3):
        client = await rosbridge(token=token)
        await client.send(op="publish", topic="battery", msg={"percentage": 0.12})
        await events_of("battery_low")
        await client.close()
    await events_of("robot_disconnected")
    client = await rosbridge(token=token)
    await client.send(op="publish", topic="battery", msg={"percentage": 0.8})
    [charged] = await events_of("alert_cleared")
    assert charged.data == {"alert": "battery_low"}
    assert len(await events_of("battery_low")) == 1
    assert await open_alerts("battery_low") == []
    # each disconnection is an alert until the robot is back
    await wait_for(lambda: Event.objects.filter(kind="robot_connected").count() == 4)
    assert len(await events_of("robot_disconnected")) == 3
    assert await open_alerts("robot_disconnected") == []


async def wait_for(condition, wait: float = 5.0) -> None:
    deadline = time.monotonic() + wait
    while not await database_sync_to_async(condition)():
        assert time.monotonic() < deadline, "the condition never held"
        await asyncio.sleep(0.05)


async def test_a_later_goal_failing_replaces_the_open_alert_of_the_last(rosbridge, robot):
    _, token = robot
    client = await rosbridge(token=token)
    for goal in ("g1", "g2"):
        status = {"goal_id": {"id": goal}, "status": 4, "text": f"no path for {goal}"}
        msg = {"header": {"frame_id": ""}, "status_list": [status]}
        await client.send(op="publish", topic="nav_status", msg=msg)
    await wait_for(lambda: Event.objects.filter(kind="goal_aborted").count() == 2)
    [still_open] = await open_alerts("goal_aborted")
    assert still_open.data["goal"] == "g2"
