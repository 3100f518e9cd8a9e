"""A robot that streams its camera's depth with no running mapping session is told so on
its latched ``mapping`` topic (once, until a session of it starts and ends), through the
real server; nothing of its frames is read or kept."""

from __future__ import annotations

import asyncio
import json
from typing import Any

import numpy as np
import pytest
from asgiref.sync import sync_to_async

from cloudnav_core import topics
from cloudnav_core.messages import compressed_depth
from maps.mapping.runner import NOT_MAPPING
from maps.models import Keyframe, MappingSession
from tests.conftest import make_robot
from tests.fixtures_live import robot_listening

pytestmark = pytest.mark.django_db(transaction=True)

DEADLINE = 60.0
"""Seconds the server's mapping runner may take to look at the robots (every second,
slower on a loaded machine)."""


def _depth(stamp: float) -> Any:
    return compressed_depth("camera_optical_frame", np.full((48, 64), 2.0, np.float32), stamp)


async def _told(robot: Any) -> dict[str, Any]:
    """Stream depth until the robot's ``mapping`` topic says something; what it said.
    (``nothing_more`` waits; a receive that timed out would end the connection.)"""
    async with asyncio.timeout(DEADLINE):
        stamp = 1.0
        while True:
            await robot.send(op="publish", topic=topics.CAMERA_DEPTH, msg=_depth(stamp))
            stamp += 0.2
            while not await robot.nothing_more(1.0):
                frame = await robot.receive()
                if frame.get("op") == "publish" and frame["topic"] == topics.MAPPING:
                    return json.loads(frame["msg"]["data"])


@pytest.mark.timeout(120)
async def test_a_robot_streaming_with_no_session_is_told_and_nothing_is_kept(
    rosbridge: Any,
) -> None:
    _, token = await sync_to_async(make_robot)()
    robot = await robot_listening(rosbridge, token, topics.MAPPING)
    news = await _told(robot)
    assert news == {"session": None, "event": "not_mapping", "reason": NOT_MAPPING}
    await robot.send(op="publish", topic=topics.CAMERA_DEPTH, msg=_depth(100.0))
    await robot.sync()
    assert await robot.quiet()  # said once, not for every frame
    assert await MappingSession.objects.acount() == 0
    assert await Keyframe.objects.acount() == 0
