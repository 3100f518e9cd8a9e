"""One robot cannot poison the fleet state of the others (issue 9, point 5).

A pose that is not finite, a Map ID longer than its column or with a NUL byte are refused
where they arrive; a row the database refuses all the same (its robot deleted meanwhile)
is written alone, never holding back the rows of the other robots; ``/api/fleet/`` answers
even for a row stored before these checks.
"""

from __future__ import annotations

import asyncio
import json
import math
import time
import urllib.request

import pytest
import websockets
from channels.db import database_sync_to_async
from rest_framework.test import APIClient

from robots.models import Robot, RobotState
from telemetry.rosbridge import fleet_state as fleet
from tests.conftest import make_robot

pytestmark = pytest.mark.django_db(transaction=True)

GOOD = {"header": {"frame_id": "boccioni_1/Hall"}, "pose": {"position": {"x": 1.0, "y": 2.0}}}


def pose_at(x, y=0.0, frame="boccioni_1/Hall"):
    return {"header": {"frame_id": frame}, "pose": {"position": {"x": x, "y": y}}}


@pytest.fixture
def robots(building, settings):
    settings.CLOUDNAV_FLEET_FLUSH_INTERVAL = 0.05
    return {name: make_robot(name=name, buildings=[building]) for name in ("r1", "r2")}


def state_of(name):
    return RobotState.objects.filter(robot__name=name).first()


async def eventually(check, wait=5.0):
    deadline = time.monotonic() + wait
    while not await database_sync_to_async(check)():
        assert time.monotonic() < deadline, "the condition never held"
        await asyncio.sleep(0.02)


def fleet_answer(user):
    client = APIClient()
    client.force_authenticate(user)
    return client.get("/api/fleet/")


@pytest.mark.parametrize("bad", ["nan", "inf", "-inf", "1e999"])
async def test_a_pose_that_is_not_finite_is_not_kept(rosbridge, robots, viewer, bad):
    client = await rosbridge(token=robots["r1"][1])
    await client.send(op="publish", topic="pose", msg=GOOD)
    await eventually(lambda: (s := state_of("r1")) is not None and s.x == 1.0)
    await client.send(op="publish", topic="pose", msg=pose_at(bad))
    await client.send(op="publish", topic="pose", msg=pose_at(3.0, bad))
    await client.sync()
    await asyncio.sleep(0.2)  # several flushes
    state = await database_sync_to_async(state_of)("r1")
    assert (state.x, state.y) == (1.0, 2.0)
    await client.close()
    answer = await database_sync_to_async(fleet_answer)(viewer)
    assert answer.status_code == 200


def test_the_fleet_answers_for_a_row_stored_before_poses_were_checked(robots, viewer):
    RobotState.objects.create(robot=robots["r1"][0], online=False, x=math.inf, y=-math.inf)
    answer = fleet_answer(viewer)
    assert answer.status_code == 200
    entry = next(e for e in answer.json() if e["robot"] == "r1")
    assert (entry["x"], entry["y"]) == (None, None)


@pytest.mark.parametrize("bad", ["b/" + "x" * 100, "boccioni_1/Ha\x00ll", "boccioni_1/\nHall"])
async def test_a_map_id_the_column_cannot_hold_is_refused_and_others_are_written(
    rosbridge, robots, bad
):
    r1 = await rosbridge(token=robots["r1"][1])
    r2 = await rosbridge(token=robots["r2"][1])
    await r1.send(op="publish", topic="map_id", msg={"data": "boccioni_1/Hall"})
    await eventually(lambda: (s := state_of("r1")) is not None and s.map_id == "boccioni_1/Hall")
    await r1.send(op="publish", topic="map_id", msg={"data": bad})
    await r1.send(op="publish", topic="pose", msg=pose_at(5.0, frame=bad))
    await r2.send(op="publish", topic="map_id", msg={"data": "boccioni_1/CorridorA"})
    await eventually(lambda: (s := state_of("r2")) is not None and s.map_id.endswith("CorridorA"))
    await eventually(lambda: state_of("r1").x == 5.0)  # the pose is kept, without its frame
    assert (await database_sync_to_async(state_of)("r1")).map_id == "boccioni_1/Hall"


def test_a_row_the_database_refuses_does_not_block_the_others(robots):
    gone, _ = make_robot(name="gone")
    gone_pk = gone.pk
    Robot.objects.filter(pk=gone_pk).delete()
    batch = {gone_pk: fleet._Entry(map_id="b/m"), robots["r1"][0].pk: fleet._Entry(map_id="b/m")}
    failed = fleet.write_states(batch)
    assert failed == {gone_pk}
    assert state_of("r1").map_id == "b/m"


@pytest.mark.scaled
async def test_on_postgresql_a_bad_map_id_blocks_nobody(scaled_servers):
    cluster = scaled_servers(1)
    live = cluster.servers[0]
    async with (
        websockets.connect(live.rosbridge_url(cluster.tokens["r1"])) as r1,
        websockets.connect(live.rosbridge_url(cluster.tokens["r2"])) as r2,
    ):
        for data in ("b/" + "x" * 120, "boccioni_1/\x00"):
            await r1.send(json.dumps({"op": "publish", "topic": "map_id", "msg": {"data": data}}))
        await r2.send(json.dumps({"op": "publish", "topic": "map_id", "msg": {"data": "b/ok"}}))
        deadline = time.monotonic() + 5
        while True:
            entries = await asyncio.to_thread(_fleet_of, live, cluster.cookies["viewer"])
            if entries.get("r2", {}).get("map_id") == "b/ok":
                break
            assert time.monotonic() < deadline, entries
            await asyncio.sleep(0.1)
        assert entries["r1"]["map_id"] == ""


def _fleet_of(live, cookie):
    request = urllib.request.Request(f"{live.url}/api/fleet/", headers={"Cookie": cookie})
    with urllib.request.urlopen(request, timeout=5) as answer:
        return {e["robot"]: e for e in json.loads(answer.read())}
