"""A visual mapping session end to end: a camera-only simulated robot (``--sensors
rgbd``) in its own process sends its camera through a real server, the server's mapping
runner tracks it, writes the grid from the keyframes' depth, serves its 3D maps so far,
and publishing makes a sub-map version whose relocalisation map is the session's
keyframes, with its PLY cloud and OctoMap beside it."""

from __future__ import annotations

import io
import json
import time
from pathlib import Path
from typing import Any

import httpx
import numpy as np
import plyfile
import pyoctomap
import pytest
import websockets
from asgiref.sync import sync_to_async

from maps.models import Building, Keyframe, MappingSession, SubMap
from robots.models import Robot
from tests.fixtures_live import LiveServer, agent_process, operator_handshake, until
from tests.support.agent_operator import Operator
from tests.support.mapping_sessions import _session

pytestmark = [pytest.mark.django_db(transaction=True), pytest.mark.slow]

ROBOT = "robot_0"
START = "5.0,23.0,0.0"


def _start() -> MappingSession:
    from maps.mapping import sessions

    robot = Robot.objects.get(name=ROBOT)
    building = robot.buildings.get()
    return sessions.start(robot, building, "VisualPorch", update=False, kind=MappingSession.VISUAL)


def _finish_and_publish(pk: int) -> SubMap:
    from maps.mapping import sessions

    session = MappingSession.objects.select_related("robot", "building", "submap").get(pk=pk)
    finished = sessions.change_state(session, MappingSession.FINISHED, (MappingSession.RUNNING,))
    version = sessions.publish(
        MappingSession.objects.select_related("robot", "building", "submap").get(pk=finished.pk)
    )
    return version.submap


def _candidate(session: MappingSession) -> Any:
    from maps.mapping import sessions

    return sessions.candidate(session)


async def _online() -> bool:
    from robots.models import RobotState, is_online

    state = await RobotState.objects.filter(robot__name=ROBOT).afirst()
    return state is not None and is_online(state)


@pytest.fixture
def camera_only_agent(daphne_server: LiveServer, tokens: Path, tmp_path: Path) -> Any:
    """``robot_0`` with an RGB-D camera and no laser, depth with every frame, in Corridor A
    facing its textured length (the demo's start faces a plain wall at 0.45 m, which
    tracking cannot place: see docs/design.md, "Visual SLAM sessions")."""
    token = json.loads(tokens.read_text())[ROBOT]
    options = ("--sensors", "rgbd", "--depth-rate", "5", "--no-visual", "--start", START)
    with agent_process(daphne_server.url, token, tmp_path / "agent.log", *options) as log:
        yield log


async def test_a_camera_only_robot_maps_through_the_server_into_a_sub_map_version(
    daphne_server: LiveServer, camera_only_agent: Path
) -> None:
    await until(_online, "the robot online", 45)
    session = await sync_to_async(_start)()

    def mapped() -> bool:
        stats = _session(session.pk).stats
        return stats.get("frames", 0) >= 10 and stats.get("keyframes", 0) >= 4

    handshake = await sync_to_async(operator_handshake)(daphne_server)
    async with websockets.connect(
        daphne_server.rosbridge_url(), additional_headers=handshake
    ) as ws:
        operator = Operator(ws)
        lock = await operator.call("/cloudnav/teleop_lock", {"robot": ROBOT}, "lock")
        assert lock["values"]["success"] is True
        # Turning on the spot: a keyframe every 15 degrees, tracked at 5 frames/s.
        turn = {"linear": {"x": 0, "y": 0, "z": 0}, "angular": {"x": 0, "y": 0, "z": 0.4}}
        give_up = time.monotonic() + 90
        while not await sync_to_async(mapped)():
            assert time.monotonic() < give_up, f"never mapped (see {camera_only_agent})"
            await operator.send(op="publish", topic=f"/{ROBOT}/cmd_vel", msg=turn)
            await operator.read_for(0.2)
    live = await sync_to_async(_session)(session.pk)
    assert live.state == MappingSession.RUNNING
    grid = (await sync_to_async(_candidate)(live)).grid  # from the keyframes' depth
    assert (grid == 100).any()  # the corridor's walls
    assert (grid == 0).any()  # its floor
    assert live.stats["lost"] == 0
    assert live.stats["refused"] == 0
    async with httpx.AsyncClient(base_url=daphne_server.url, headers=handshake) as http:
        so_far = await http.get(f"/api/mapping/sessions/{session.pk}/cloud.ply", timeout=60)
        assert so_far.status_code == 200
        cloud = plyfile.PlyData.read(io.BytesIO(so_far.content))["vertex"]
        assert cloud.count > 1000
        height = np.asarray(cloud["z"])
        assert height.min() > -0.1  # nothing below the floor...
        assert height.max() > 1.0  # ...and the corridor's walls standing up
        submap = await sync_to_async(_finish_and_publish)(session.pk)
        building = await sync_to_async(lambda: submap.building.code)()
        version = f"/api/buildings/{building}/maps/VisualPorch/versions/1"
        published = await http.get(f"{version}/cloud.ply")
        assert plyfile.PlyData.read(io.BytesIO(published.content))["vertex"].count > 1000
        octomap = await http.get(f"{version}/octomap.bt")
        assert octomap.status_code == 200
    path = camera_only_agent.parent / "map.bt"
    path.write_bytes(octomap.content)
    tree = pyoctomap.OcTree(0.1)
    assert tree.readBinary(str(path))
    occupied = sum(tree.isNodeOccupied(leaf.current_node) for leaf in tree.begin_leafs())
    assert occupied > 100
    assert submap.code == "VisualPorch"
    assert submap.revision == 1
    assert await Keyframe.objects.filter(submap=submap, robot=ROBOT).acount() >= 4
    assert await Building.objects.filter(submaps=submap).aexists()
