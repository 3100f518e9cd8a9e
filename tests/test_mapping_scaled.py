"""Scaled mode: a robot connected to one server process maps (that process runs its
SLAM), an admin on another process watches, finishes and publishes the map as the
sub-map's next version, and the robot's conditional bundle request gets it."""

from __future__ import annotations

import asyncio
import contextlib
import json
import time
from typing import Any

import httpx
import pytest
import websockets

from tests.fixtures_live import run_manage
from tests.support.mapping_sessions import tour_messages

pytestmark = [pytest.mark.scaled, pytest.mark.slow]

SESSIONS = "/api/mapping/sessions/"
BUNDLE = "/api/buildings/boccioni_1/maps/Lab/bundle"
ADMIN = ("admin", "pw-admin")
DEADLINE = 60.0

# An admin of the seeded building, and the sub-map Lab (version 1) the robot will update.
SETUP = """
import django
django.setup()
from maps.models import Building
from tests.conftest import make_submap, make_user
building = Building.objects.get(code="boccioni_1")
building.members.add(make_user("admin", "admin"))
make_submap(building, code="Lab")
"""


async def until(check: Any, what: str) -> Any:
    """Await ``check()`` until it answers something true; fail naming ``what``."""
    deadline = time.monotonic() + DEADLINE
    while not (found := await check()):
        assert time.monotonic() < deadline, f"timed out waiting for {what}"
        await asyncio.sleep(0.25)
    return found


async def drive(socket: Any, messages: list[tuple[dict[str, Any], dict[str, Any]]]) -> None:
    """The robot's tour, at about 20 scans a second, round and round until cancelled."""
    await socket.send(json.dumps({"op": "advertise", "topic": "odom", "type": "nav_msgs/Odometry"}))
    await socket.send(
        json.dumps({"op": "advertise", "topic": "scan", "type": "sensor_msgs/LaserScan"})
    )
    while True:
        for odom, scan in messages:
            await socket.send(json.dumps({"op": "publish", "topic": "odom", "msg": odom}))
            await socket.send(json.dumps({"op": "publish", "topic": "scan", "msg": scan}))
            await asyncio.sleep(0.05)


async def test_a_robot_maps_on_one_process_and_an_admin_on_another_publishes_it(
    scaled_servers: Any,
) -> None:
    cluster = scaled_servers(2)
    await asyncio.to_thread(run_manage, cluster.database_url, "-c", SETUP)
    here, there = cluster.servers  # the robot's process, the admin's
    messages = await asyncio.to_thread(tour_messages)
    robot_http = httpx.AsyncClient(
        base_url=here.url, headers={"Authorization": f"Token {cluster.tokens['r1']}"}
    )
    admin = httpx.AsyncClient(base_url=there.url, auth=ADMIN)
    async with (
        robot_http,
        admin,
        websockets.connect(here.rosbridge_url(cluster.tokens["r1"])) as robot,
    ):
        held = await robot_http.get(BUNDLE)
        assert held.status_code == 200
        assert held.json()["revision"] == 1

        async def started() -> Any:
            body = {"robot": "r1", "building": "boccioni_1", "code": "Lab", "update": True}
            answer = await admin.post(SESSIONS, json=body)
            return answer.json() if answer.status_code == 201 else None  # 409 until online

        session = await until(started, "a session for the robot once it is online")
        url = f"{SESSIONS}{session['id']}/"
        driving = asyncio.create_task(drive(robot, messages))
        try:

            async def mapped() -> bool:
                seen = (await admin.get(url)).json()
                return seen["snapshot"] >= 2 and seen["stats"].get("matched", 0) >= 50

            await until(mapped, "the map growing, seen from the admin's process")
            grid = await admin.get(f"{url}grid")
            assert grid.json()["info"]["width"] > 50
            finished = await admin.post(f"{url}finish")
            assert finished.json()["state"] == "finished"
        finally:
            driving.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await driving
        published = await admin.post(f"{url}publish", json={"note": "mapped across processes"})
        assert published.status_code == 201, published.text
        assert (published.json()["number"], published.json()["reason"]) == (2, "mapping")

        newer = await robot_http.get(BUNDLE, headers={"If-None-Match": held.headers["ETag"]})
        assert newer.status_code == 200
        assert newer.json()["revision"] == 2
        assert newer.headers["ETag"].startswith('"v2-')
        again = await robot_http.get(BUNDLE, headers={"If-None-Match": newer.headers["ETag"]})
        assert again.status_code == 304
