"""A robot that streams its camera's depth with no running mapping session is told so on
its latched ``mapping`` topic (once, until a session of it starts and ends), through the
real server; nothing of its frames is read or kept. The robot agent (simulated or a ROS
bridge: both declare their topics with ``robots.agent.robot.declare``) subscribes to that
topic and logs why, once."""

from __future__ import annotations

import asyncio
import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from asgiref.sync import sync_to_async

from cloudnav_core import topics
from cloudnav_core.messages import MappingNews, compressed_depth, mapping_message, mapping_news_of
from maps.mapping.runner import NOT_MAPPING
from maps.models import Keyframe, MappingSession
from tests.conftest import make_robot
from tests.fixtures_live import LiveServer, agent_process, robot_listening, until

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


def test_the_news_on_the_mapping_topic_reads_back_as_it_was_said() -> None:
    for news in (MappingNews(None, "not_mapping", NOT_MAPPING), MappingNews(4, "started")):
        assert mapping_news_of(mapping_message(news)) == news
    assert json.loads(mapping_message(MappingNews(4, "saved"))["data"]) == {
        "session": 4,
        "event": "saved",
    }
    for garbled in ({"data": "{}"}, {"data": "not json"}, {"data": '{"session": "4", "event": 1}'}):
        assert mapping_news_of(garbled) is None


@pytest.mark.slow  # a live server and an agent process: about 30 s
@pytest.mark.timeout(180)
async def test_a_camera_only_agent_streaming_with_no_session_logs_why_once(
    daphne_server: LiveServer, demo_token: str, tmp_path: Path
) -> None:
    options = ("--sensors", "rgbd", "--depth-rate", "5", "--no-visual")
    with agent_process(daphne_server.url, demo_token, tmp_path / "agent.log", *options) as log:
        await until(lambda: NOT_MAPPING in log.read_text(errors="replace"), "the reason", 90)
        await asyncio.sleep(5.0)  # depth streams on at 5 frames/s
        said = log.read_text(errors="replace")
    assert said.count(NOT_MAPPING) == 1, said
    assert "WARNING robots.agent.robot: the cloud is not mapping this robot" in said
    assert await MappingSession.objects.acount() == 0
