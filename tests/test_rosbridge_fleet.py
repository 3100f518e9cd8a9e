"""Fleet state: online, pose, Map ID and last seen, written in the background and served
at /api/fleet/."""

from __future__ import annotations

import math
import time
from typing import Any

import pytest
from channels.db import database_sync_to_async
from rest_framework.test import APIClient

from robots.models import RobotState
from tests.conftest import make_building, make_robot
from tests.fixtures_live import until

pytestmark = pytest.mark.django_db(transaction=True)

POSE = {
    "header": {"frame_id": "boccioni_1/CorridorA", "stamp": {"secs": 3, "nsecs": 0}},
    "pose": {
        "position": {"x": 1.5, "y": -2.0, "z": 0.0},
        "orientation": {"x": 0.0, "y": 0.0, "z": math.sin(0.25), "w": math.cos(0.25)},
    },
}


@pytest.fixture
def robot(building, settings):
    settings.CLOUDNAV_FLEET_FLUSH_INTERVAL = 0.05
    return make_robot(name="r1", buildings=[building])


def state_of(robot):
    return RobotState.objects.filter(robot=robot).first()


async def eventually(check, wait=5.0):
    """Poll ``check`` (run in a thread with database access) until it is true or time runs out."""
    await until(database_sync_to_async(check), "the condition", wait)


async def test_a_connected_robot_is_online_and_offline_when_it_leaves(rosbridge, robot):
    record, token = robot
    client = await rosbridge(token=token)
    await eventually(lambda: (s := state_of(record)) is not None and s.online)
    await client.close()
    await eventually(lambda: not state_of(record).online)


async def test_the_pose_and_map_id_are_kept(rosbridge, robot):
    record, token = robot
    client = await rosbridge(token=token)
    await client.send(op="publish", topic="pose", msg=POSE)

    def written():
        state = state_of(record)
        return state is not None and state.x == 1.5 and state.map_id == "boccioni_1/CorridorA"

    await eventually(written)
    state = await database_sync_to_async(state_of)(record)
    assert state.y == -2.0
    assert state.yaw == pytest.approx(0.5)
    await client.send(op="publish", topic="map_id", msg={"data": "boccioni_1/Hall"})
    await eventually(lambda: state_of(record).map_id == "boccioni_1/Hall")


async def test_the_version_a_robot_holds_is_kept_apart_from_its_map_id(rosbridge, robot):
    record, token = robot
    client = await rosbridge(token=token)
    await client.send(op="publish", topic="map_id", msg={"data": "boccioni_1/Hall@v4"})
    await eventually(lambda: (s := state_of(record)) is not None and s.map_version == 4)
    assert (await database_sync_to_async(state_of)(record)).map_id == "boccioni_1/Hall"


async def test_state_is_not_written_once_per_message(rosbridge, robot, settings, monkeypatch):
    from telemetry.rosbridge import fleet_state as fleet

    settings.CLOUDNAV_FLEET_FLUSH_INTERVAL = 0.3
    writes = []
    write_states = fleet.write_states

    def counted(batch: Any) -> Any:
        writes.append(1)
        return write_states(batch)

    monkeypatch.setattr(fleet, "write_states", counted)
    record, token = robot
    started = time.monotonic()
    client = await rosbridge(token=token)
    for n in range(200):
        pose = {**POSE, "pose": {"position": {"x": n, "y": 0}}}
        await client.send(op="publish", topic="pose", msg=pose)
    await client.sync()
    await eventually(lambda: (s := state_of(record)) is not None and s.x == 199)
    # one write when it connected, then at most one per interval, however many messages
    assert len(writes) <= 2 + (time.monotonic() - started) / 0.3
    assert len(writes) < 200


def fleet_of(principal=None, token=None):
    client = APIClient()
    if principal is not None:
        client.force_authenticate(principal)
    if token is not None:
        client.credentials(HTTP_AUTHORIZATION=f"Token {token}")
    return client.get("/api/fleet/")


@pytest.mark.parametrize("persona", ["admin", "operator", "viewer"])
def test_people_of_the_building_see_its_robots(robot, persona, request):
    RobotState.objects.create(robot=robot[0], online=True, map_id="boccioni_1/Hall", x=1.0)
    response = fleet_of(request.getfixturevalue(persona))
    assert response.status_code == 200
    [entry] = response.json()
    assert entry["robot"] == "r1"
    assert entry["map_id"] == "boccioni_1/Hall"
    assert entry["buildings"] == ["boccioni_1"]


def test_a_robot_without_state_is_listed_offline(robot, viewer):
    [entry] = fleet_of(viewer).json()
    assert entry["online"] is False
    assert entry["x"] is None


def test_a_stale_row_shows_offline(robot, viewer):
    from datetime import UTC, datetime, timedelta

    RobotState.objects.create(
        robot=robot[0], online=True, last_seen=datetime.now(UTC) - timedelta(minutes=5)
    )
    [entry] = fleet_of(viewer).json()
    assert entry["online"] is False


def test_it_rejects_outsider(robot, outsider):
    assert fleet_of(outsider).status_code == 403


def test_it_rejects_anonymous(robot):
    assert fleet_of().status_code in (401, 403)


def test_a_robot_sees_its_buildings_fleet(robot, building):
    _, token = make_robot(name="r2", buildings=[building])
    names = [e["robot"] for e in fleet_of(token=token).json()]
    assert names == ["r1", "r2"]


def test_a_robot_of_another_building_does_not_see_it(robot):
    other = make_building(code="elsewhere", name="Elsewhere")
    _, token = make_robot(name="rx", buildings=[other])
    assert [e["robot"] for e in fleet_of(token=token).json()] == ["rx"]


def test_it_filters_by_building(robot, admin):
    other = make_building(code="elsewhere", name="Elsewhere", members=[admin])
    make_robot(name="rx", buildings=[other])
    response = APIClient()
    response.force_authenticate(admin)
    names = [e["robot"] for e in response.get("/api/fleet/?building=elsewhere").json()]
    assert names == ["rx"]
