"""A robot that wakes up with no tag in view asks the cloud where it is, and goes on.

A server (daphne) and the robot agent, separate processes. Keyframes of Atrium 1 are in
the cloud (sent over HTTP as a robot sends them). The robot starts in the middle of the
atrium, farther than two metres from every tag, with no map; an operator sends it to
Corridor B. It turns on the spot asking the cloud with what its camera sees, is placed
by the answer ("visual relocalisation"), downloads Atrium 1's bundle, and drives through
the doorway to its goal in the next sub-map.
"""

from __future__ import annotations

import math
import time
from collections.abc import Iterator
from pathlib import Path

import httpx
import pytest
import websockets

from robots.agent.sim.camera import Camera
from robots.agent.sim.world import demo_world
from robots.agent.visual import keyframe_document
from tests.fixtures_live import LiveServer, agent_process
from tests.support.end_to_end import Operator, position_error
from tests.support.logs import tail

pytestmark = [pytest.mark.django_db(transaction=True), pytest.mark.slow]

START = (24.5, 24.0, 2.0)  # clear of the atrium's furniture, 3 m and more from every tag
CORRIDOR_B = (21.5, 14.0, -math.pi / 2)
SURVEY = [
    (x, y, yaw)
    for x in (23.5, 24.5, 25.5)
    for y in (23.0, 24.0, 25.0)
    for yaw in [k * math.pi / 4 for k in range(8)]
    if demo_world().disc_is_free(x, y, 0.3)
]


def send_survey(server: LiveServer, token: str) -> None:
    """Keyframes of Atrium 1, as a robot that knew its pose would have sent them."""
    camera = Camera(demo_world(server.url))
    url = f"{server.url}/api/buildings/boccioni_1/maps/Atrium1/keyframes"
    with httpx.Client(headers={"Authorization": f"Token {token}"}, timeout=30) as client:
        for pose in SURVEY:
            image, depth = camera.capture(pose)
            assert depth is not None
            body = keyframe_document(camera.model, pose, image, depth)
            while (answer := client.post(url, json=body)).status_code == 503:
                time.sleep(0.2)  # the queue is full: the worker catches up
            assert answer.status_code == 202, answer.text
        deadline = time.monotonic() + 60
        while len(client.get(url).json()["keyframes"]) < 0.8 * len(SURVEY):
            assert time.monotonic() < deadline
            time.sleep(0.5)


@pytest.fixture
def agent(daphne_server: LiveServer, demo_token: str, tmp_path: Path) -> Iterator[Path]:
    send_survey(daphne_server, demo_token)
    start = ",".join(str(v) for v in START)
    options = ["--time-scale", "4", "--camera-rate", "1", "--start", start]
    with agent_process(daphne_server.url, demo_token, tmp_path / "agent.log", *options) as log:
        yield log


async def test_a_robot_with_no_tag_in_view_is_placed_by_the_cloud_and_reaches_its_goal(
    daphne_server: LiveServer, operator_headers: dict[str, str], agent: Path
) -> None:
    url = daphne_server.rosbridge_url()
    async with websockets.connect(url, additional_headers=operator_headers) as ws:
        operator = Operator(ws)
        await operator.watch()
        await operator.until_listening(agent)
        await operator.send_goal("CorridorB", CORRIDOR_B)
        await operator.until_succeeded("goal_1", agent)
        await operator.pump(0.5)
    log = agent.read_text(errors="replace")  # noqa: ASYNC240 (the run is over)
    assert "placed by the cloud in boccioni_1/Atrium1" in log, tail(agent)
    assert operator.pose is not None
    assert operator.pose["header"]["frame_id"] == "boccioni_1/CorridorB"
    assert position_error(operator.pose, CORRIDOR_B) < 0.3
