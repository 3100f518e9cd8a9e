"""The paper's scenario end to end: a server (daphne) and a robot agent, separate processes.

A robot with no maps, placed before the entrance tag of the demo building, is sent to
Office 7 by an operator; it reads each tag, downloads each sub-map on its way once, and
arrives. Sent back to Corridor A, it downloads nothing. What is checked comes from the
server's side: its access log (every bundle request and its status) and the robot's
``/robot_0/pose`` and ``nav_status`` topics as an operator receives them.

The building is alive: ``PEOPLE`` people walk seeded routes through it (crossing the
robot's way, pausing, some walking towards it), seen by its laser and camera.

The agent runs the simulation ``TIME_SCALE`` times faster than the wall clock.
"""

from __future__ import annotations

import math
import re
import time
from collections import Counter
from collections.abc import Iterator
from pathlib import Path

import pytest
import websockets

from maps.domain.demo_building import PAPER_ROUTE
from tests.fixtures_live import ACCESS_LOG_ALL, LiveServer, LiveServers, agent_process
from tests.support.end_to_end import BUILDING, Operator, position_error

# Two legs of up to LEG_DEADLINE each, and the setting out.
pytestmark = [pytest.mark.django_db(transaction=True), pytest.mark.slow, pytest.mark.timeout(900)]

TIME_SCALE = 8.0
PEOPLE, PEOPLE_SEED = 6, 2
ROUTE = list(PAPER_ROUTE)
OFFICE_7 = (47.7, 27.5, 0.0)
CORRIDOR_A = (10.0, 23.2, math.pi)
BUNDLE = re.compile(r'"GET /api/buildings/([^/]+)/maps/([^/]+)/bundle" (\d{3})')


@pytest.fixture
def daphne_server(daphne_servers: LiveServers) -> LiveServer:
    """The live server, its access log with the unchanged bundle checks (304) these tests
    count."""
    return daphne_servers.start(env=ACCESS_LOG_ALL)


@pytest.fixture
def agent(daphne_server: LiveServer, demo_token: str, tmp_path: Path) -> Iterator[Path]:
    """``python -m robots.agent`` in its own process; yields its log file."""
    # Tags only: the visual map has its own end-to-end test (test_visual_wake_up.py), and
    # its keyframes (a megabyte each) at 8 x real time would load this one's server.
    options = ["--time-scale", str(TIME_SCALE), "--camera-rate", "1", "--depth-rate", "0"]
    options.append("--no-visual")
    options += ["--people", str(PEOPLE), "--people-seed", str(PEOPLE_SEED)]
    with agent_process(daphne_server.url, demo_token, tmp_path / "agent.log", *options) as log:
        yield log


def bundle_answers(server: LiveServer) -> list[tuple[str, int]]:
    """``(map code, HTTP status)`` of each bundle request in the server's access log."""
    return [(m.group(2), int(m.group(3))) for m in BUNDLE.finditer(server.log())]


async def test_a_robot_with_no_maps_crosses_the_building_and_back(
    daphne_server: LiveServer, operator_headers: dict[str, str], agent: Path
) -> None:
    started = time.monotonic()
    url = daphne_server.rosbridge_url()
    async with websockets.connect(url, additional_headers=operator_headers) as ws:
        operator = Operator(ws)
        await operator.watch()
        await operator.until_listening(agent)
        await operator.send_goal("Office7", OFFICE_7)
        await operator.until_succeeded("goal_1", agent)
        await operator.pump(0.5)
        there = operator.pose
        outward = bundle_answers(daphne_server)

        await operator.send_goal("CorridorA", CORRIDOR_A)
        await operator.until_succeeded("goal_2", agent)
        await operator.pump(0.5)
        back = operator.pose
    downloads = Counter(code for code, status in bundle_answers(daphne_server) if status == 200)

    assert there is not None
    assert there["header"]["frame_id"] == f"{BUILDING}/Office7"
    assert position_error(there, OFFICE_7) < 0.3
    assert sorted(code for code, status in outward if status == 200) == sorted(ROUTE)
    assert back is not None
    assert back["header"]["frame_id"] == f"{BUILDING}/CorridorA"
    assert position_error(back, CORRIDOR_A) < 0.3
    assert all(count == 1 for count in downloads.values())  # each sub-map downloaded once
    returned = bundle_answers(daphne_server)[len(outward) :]
    assert returned
    assert {status for _, status in returned} == {304}  # the way back: revalidations only
    print(f"end to end: {time.monotonic() - started:.0f} s")
