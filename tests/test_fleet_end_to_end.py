"""Two robots sent to one spot, in the simulator end to end (issue 28, points 1 and 5):
the demo's first two robots, one agent process, localise from the entrance tag; an
operator sends robot_0 to where robot_1 stands. The server moves the goal to the nearest
free spot and says so; robot_0 gets there and stops beside robot_1, never on it."""

from __future__ import annotations

import io
import math
import time
from pathlib import Path
from typing import Any

import pytest
import websockets
from django.core.management import call_command

from tests.fixtures_live import LiveServer, fleet_process, operator_handshake
from tests.support.demo_operator import LOCALISED_WITHIN, Operator, state_of
from tests.support.logs import tail

pytestmark = [pytest.mark.django_db(transaction=True), pytest.mark.slow]

ROBOTS = ("robot_0", "robot_1")
AGENT_OPTIONS = ("--time-scale", "2", "--no-visual", "--camera-rate", "1", "--depth-rate", "0")
DRIVE_WITHIN = 60.0  # wall seconds for a drive of a few metres at twice real time
SPOT_APART = 0.5  # two robots' spots (footprint plus margin) overlap nearer than this
NO_CONTACT = 0.36  # two bodies of 0.18 m radius
SUCCEEDED, FAILED = 3, {2, 4, 5, 8, 9}


@pytest.fixture
def tokens(tmp_path: Path) -> Path:
    path = tmp_path / "tokens.json"
    call_command("seed_demo", "--robots", "2", "--tokens-file", str(path), stdout=io.StringIO())
    return path


@pytest.fixture
def handshake(daphne_server: LiveServer, tokens: Path) -> dict[str, str]:
    return operator_handshake(daphne_server)


def at(pose: dict[str, Any]) -> tuple[float, float]:
    position = pose["pose"]["position"]
    return position["x"], position["y"]


def apart(operator: Operator) -> float:
    first, second = (operator.latest[f"/{robot}/pose"] for robot in ROBOTS)
    if first["header"]["frame_id"] != second["header"]["frame_id"]:
        return math.inf
    return math.dist(at(first), at(second))


async def test_a_robot_sent_where_another_stands_stops_beside_it(
    daphne_server: LiveServer, tokens: Path, handshake: dict[str, str], tmp_path: Path
) -> None:
    agent = fleet_process(daphne_server.url, tokens, 2, tmp_path / "agent.log", *AGENT_OPTIONS)
    with agent as log:
        url = daphne_server.rosbridge_url()
        async with websockets.connect(url, additional_headers=handshake) as ws:
            operator = Operator(ws)
            await ws.send('{"op": "set_level", "level": "warning"}')
            topics = [f"/{r}/{t}" for r in ROBOTS for t in ("localisation", "pose", "nav_status")]
            await operator.subscribe(*topics)

            def localised() -> bool:
                states = [state_of(operator.latest.get(f"/{r}/localisation")) for r in ROBOTS]
                poses = [f"/{r}/pose" in operator.latest for r in ROBOTS]
                return all(s.get("state") == "localised" for s in states) and all(poses)

            await operator.until(localised, LOCALISED_WITHIN, log)
            standing = operator.latest["/robot_1/pose"]
            spot = at(standing)
            await operator.publish("/robot_0/goal", standing)
            await operator.until(lambda: bool(operator.statuses), 20, log)
            told = operator.statuses[0]["msg"]
            assert "Moved to the nearest free spot" in told
            assert "robot_1 stands at" in told

            nearest = math.inf

            def goal_over() -> bool:
                nonlocal nearest
                nearest = min(nearest, apart(operator))
                statuses = operator.latest.get("/robot_0/nav_status", {}).get("status_list", [])
                return bool(statuses) and statuses[-1]["status"] in {SUCCEEDED, *FAILED}

            started = time.monotonic()
            await operator.until(goal_over, DRIVE_WITHIN, log)
            last = operator.latest["/robot_0/nav_status"]["status_list"][-1]
            assert last["status"] == SUCCEEDED, (last, tail(log))
            print(f"robot_0 drove beside robot_1 in {time.monotonic() - started:.1f} s")
            assert nearest >= NO_CONTACT
            assert math.dist(at(operator.latest["/robot_0/pose"]), spot) >= SPOT_APART - 0.15
