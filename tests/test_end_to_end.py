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

import asyncio
import contextlib
import json
import math
import re
import time
from collections import Counter
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
import websockets

from maps.domain.demo_building import PAPER_ROUTE
from tests.fixtures_live import ACCESS_LOG_ALL, LiveServer, LiveServers, agent_process

# Two legs of up to LEG_DEADLINE each, and the setting out.
pytestmark = [pytest.mark.django_db(transaction=True), pytest.mark.slow, pytest.mark.timeout(900)]

TIME_SCALE = 8.0
PEOPLE, PEOPLE_SEED = 6, 2
ROBOT = "robot_0"
BUILDING = "boccioni_1"
ROUTE = list(PAPER_ROUTE)
OFFICE_7 = (47.7, 27.5, 0.0)
CORRIDOR_A = (10.0, 23.2, math.pi)
LEG_DEADLINE = 300.0  # wall seconds for either trip; about a minute each, more when busy
SUCCEEDED, TERMINAL_FAILURES = 3, {2, 4, 5, 8, 9}
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


class Operator:
    """An operator's browser-like rosbridge session watching and commanding the robot."""

    def __init__(self, ws: Any) -> None:
        self.ws = ws
        self.pose: dict[str, Any] | None = None
        self.statuses: dict[str, tuple[int, str]] = {}
        self.heard = False  # any nav_status yet

    async def send(self, **frame: Any) -> None:
        await self.ws.send(json.dumps(frame))

    async def watch(self) -> None:
        for topic in ("pose", "nav_status"):
            await self.send(op="subscribe", topic=f"/{ROBOT}/{topic}")

    async def pump(self, wait: float) -> None:
        """Read frames for up to ``wait`` seconds, keeping the latest pose and statuses."""
        with contextlib.suppress(TimeoutError):
            frame = json.loads(await asyncio.wait_for(self.ws.recv(), wait))
            if frame.get("topic") == f"/{ROBOT}/pose":
                self.pose = frame["msg"]
            elif frame.get("topic") == f"/{ROBOT}/nav_status":
                self.heard = True
                for entry in frame["msg"]["status_list"]:
                    self.statuses[entry["goal_id"]["id"]] = (entry["status"], entry["text"])

    async def send_goal(self, map_code: str, pose: tuple[float, float, float]) -> None:
        x, y, yaw = pose
        msg = {
            "header": {"frame_id": f"{BUILDING}/{map_code}"},
            "pose": {
                "position": {"x": x, "y": y, "z": 0.0},
                "orientation": {"x": 0.0, "y": 0.0, "z": math.sin(yaw / 2), "w": math.cos(yaw / 2)},
            },
        }
        await self.send(op="publish", topic=f"/{ROBOT}/goal", msg=msg)

    async def until_succeeded(self, goal_id: str, agent_log: Path) -> None:
        give_up = time.monotonic() + LEG_DEADLINE
        while self.statuses.get(goal_id, (None,))[0] != SUCCEEDED:
            status = self.statuses.get(goal_id)
            assert status is None or status[0] not in TERMINAL_FAILURES, (status, tail(agent_log))
            assert time.monotonic() < give_up, (status, tail(agent_log))
            await self.pump(1.0)

    async def until_listening(self, agent_log: Path) -> None:
        """Until the robot's first ``nav_status``: it subscribed to its goal before it
        published anything, so a goal sent now reaches it."""
        give_up = time.monotonic() + 30
        while not self.heard:
            assert time.monotonic() < give_up, tail(agent_log)
            await self.pump(1.0)


def tail(log: Path, lines: int = 30) -> str:
    return "\n".join(log.read_text(errors="replace").splitlines()[-lines:])


def bundle_answers(server: LiveServer) -> list[tuple[str, int]]:
    """``(map code, HTTP status)`` of each bundle request in the server's access log."""
    return [(m.group(2), int(m.group(3))) for m in BUNDLE.finditer(server.log())]


def position_error(pose: dict[str, Any], goal: tuple[float, float, float]) -> float:
    position = pose["pose"]["position"]
    return math.hypot(position["x"] - goal[0], position["y"] - goal[1])


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
