"""A visual mapping session end to end: a camera-only simulated robot (``--sensors
rgbd``) in its own process sends its camera through a real server, the server's mapping
runner tracks it, writes the grid from the keyframes' depth, and publishing makes a
sub-map version whose relocalisation map is the session's keyframes."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest
from asgiref.sync import sync_to_async

from maps.models import Building, Keyframe, MappingSession, SubMap
from robots.models import Robot
from tests.fixtures_live import LiveServer, agent_process, until
from tests.test_agent_whereabouts import tokens  # noqa: F401 (the demo's robots, seeded)
from tests.test_mapping_sessions import _session

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


async def _online() -> bool:
    from robots.fleet import is_online
    from robots.models import RobotState

    state = await RobotState.objects.filter(robot__name=ROBOT).afirst()
    return state is not None and is_online(state)


@pytest.fixture
def camera_only_agent(daphne_server: LiveServer, tokens: Path, tmp_path: Path) -> Any:  # noqa: F811
    """``robot_0`` with an RGB-D camera and no laser, depth with every frame, in Corridor A
    facing its textured length (the demo's start faces a plain wall at 0.45 m, which
    tracking cannot place: see docs/design.md, "Visual SLAM sessions")."""
    token = json.loads(tokens.read_text())[ROBOT]
    options = ("--sensors", "rgbd", "--depth-rate", "5", "--no-visual", "--start", START)
    with agent_process(daphne_server.url, token, tmp_path / "agent.log", *options) as log:
        yield log


async def test_a_camera_only_robot_maps_through_the_server_into_a_sub_map_version(
    camera_only_agent: Path,
) -> None:
    await until(_online, "the robot online", 45)
    session = await sync_to_async(_start)()

    def mapped() -> bool:
        stats = _session(session.pk).stats
        return stats.get("frames", 0) >= 10 and stats.get("keyframes", 0) >= 1

    await until(sync_to_async(mapped), f"frames mapped (see {camera_only_agent})", 60)
    live = await sync_to_async(_session)(session.pk)
    assert live.state == MappingSession.RUNNING
    assert live.grid_pgm  # the grid from the keyframes' depth
    assert live.stats["lost"] == 0
    assert live.stats["refused"] == 0
    submap = await sync_to_async(_finish_and_publish)(session.pk)
    assert submap.code == "VisualPorch"
    assert submap.revision == 1
    assert await Keyframe.objects.filter(submap=submap, robot=ROBOT).acount() >= 1
    assert await Building.objects.filter(submaps=submap).aexists()
