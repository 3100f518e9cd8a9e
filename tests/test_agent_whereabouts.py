"""Where the robot says it is, seen by an operator over a real server, the agent in its own
process: ``make demo``'s robots localise from the entrance tag on their own; a robot
placed where no tag is in reach says it is lost until an operator sets its initial pose;
a goal that names no sub-map is rejected, and the robot says why."""

from __future__ import annotations

import json
import time
from pathlib import Path
from typing import Any

import pytest
import websockets

from tests.fixtures_live import LiveServer, agent_process, fleet_process, operator_handshake
from tests.support.demo_operator import (
    DEMO_ROBOTS,
    LOCALISED_WITHIN,
    Operator,
    pose,
    state_of,
)

pytestmark = [pytest.mark.django_db(transaction=True), pytest.mark.slow]

CORRIDOR_A = "boccioni_1/CorridorA"
AWAY_FROM_TAGS = (10.0, 23.2, 0.0)  # mid Corridor A: the nearest tag is 7.8 m ahead
SUCCEEDED, ABORTED, REJECTED = 3, 4, 5
CAMERA_ONLY_GOAL = (9.0, 23.2, 0.0)  # 4 to 5 m along Corridor A from the demo's start


@pytest.fixture
def handshake(daphne_server: LiveServer, tokens: Path) -> dict[str, str]:
    return operator_handshake(daphne_server)


async def test_every_demo_robot_localises_from_the_entrance_tag_soon_after_make_demo_starts(
    daphne_server: LiveServer, tokens: Path, handshake: dict[str, str], tmp_path: Path
) -> None:
    robots = [f"/robot_{i}/localisation" for i in range(DEMO_ROBOTS)]
    started = time.monotonic()
    with fleet_process(daphne_server.url, tokens, DEMO_ROBOTS, tmp_path / "agent.log") as log:
        url = daphne_server.rosbridge_url()
        async with websockets.connect(url, additional_headers=handshake) as ws:
            operator = Operator(ws)
            await operator.subscribe(*robots)

            def all_localised() -> bool:
                states = [state_of(operator.latest.get(topic)) for topic in robots]
                return all(s.get("state") == "localised" for s in states)

            await operator.until(all_localised, LOCALISED_WITHIN, log)
    print(f"all {DEMO_ROBOTS} demo robots localised {time.monotonic() - started:.1f} s after start")
    for topic in robots:
        status = operator.latest[topic]
        assert status["level"] == 0
        assert state_of(status) == {"state": "localised", "map_id": CORRIDOR_A, "source": "tag 0"}


@pytest.fixture
def lost_agent(daphne_server: LiveServer, tokens: Path, tmp_path: Path) -> Any:
    token = json.loads(tokens.read_text())["robot_0"]
    start = ",".join(str(v) for v in AWAY_FROM_TAGS)
    with agent_process(daphne_server.url, token, tmp_path / "agent.log", "--start", start) as log:
        yield log


async def test_a_robot_away_from_tags_says_it_is_lost_until_an_operator_sets_its_initial_pose(
    daphne_server: LiveServer, handshake: dict[str, str], lost_agent: Path
) -> None:
    topic = "/robot_0/localisation"
    async with websockets.connect(
        daphne_server.rosbridge_url(), additional_headers=handshake
    ) as ws:
        operator = Operator(ws)
        await operator.subscribe(topic)
        await operator.until(lambda: topic in operator.latest, 30, lost_agent)
        lost = operator.latest[topic]
        assert (lost["level"], lost["name"]) == (1, "localisation")
        assert lost["message"] == "lost, looking for a tag"
        assert state_of(lost)["state"] == "lost"

        estimate = pose(CORRIDOR_A, *AWAY_FROM_TAGS)
        estimate["pose"] = {"pose": estimate["pose"], "covariance": [0.0] * 36}
        await operator.publish("/robot_0/initialpose", estimate)
        placed = lambda: state_of(operator.latest[topic]).get("state") == "localised"  # noqa: E731
        await operator.until(placed, 15, lost_agent)
    assert operator.latest[topic]["message"] == f"localised in {CORRIDOR_A} by initial pose"


async def test_a_goal_that_names_no_sub_map_is_refused_where_it_is_sent_and_never_driven(
    daphne_server: LiveServer, handshake: dict[str, str], lost_agent: Path
) -> None:
    """The server checks goals where they are published (issue 23 point 2): the operator
    is told why, and the robot never hears of it."""
    topic = "/robot_0/nav_status"
    async with websockets.connect(
        daphne_server.rosbridge_url(), additional_headers=handshake
    ) as ws:
        operator = Operator(ws)
        await operator.ws.send(json.dumps({"op": "set_level", "level": "error"}))
        await operator.subscribe(topic)
        await operator.until(lambda: topic in operator.latest, 30, lost_agent)  # it listens
        goal = pose(CORRIDOR_A, 12.0, 23.2, 0.0)
        goal["header"]["frame_id"] = None  # what a page sent with no sub-map shown
        await operator.publish("/robot_0/goal", goal)
        await operator.until(lambda: bool(operator.statuses), 15, lost_agent)
        await operator.until(lambda: len(operator.heard[topic]) >= 3, 15, lost_agent)
    assert "frame_id" in operator.statuses[0]["msg"]
    said = [entry for msg in operator.heard[topic] for entry in msg["status_list"]]
    assert REJECTED not in {entry["status"] for entry in said}


@pytest.fixture
def camera_only_agent(daphne_server: LiveServer, tokens: Path, tmp_path: Path) -> Any:
    """``robot_0`` with an RGB-D camera and no laser, from the demo's start."""
    token = json.loads(tokens.read_text())["robot_0"]
    log_path = tmp_path / "agent.log"
    with agent_process(daphne_server.url, token, log_path, "--sensors", "rgbd") as log:
        yield log


async def test_a_camera_only_robot_localises_from_the_tag_and_drives_to_a_goal_by_its_depth(
    daphne_server: LiveServer, handshake: dict[str, str], camera_only_agent: Path
) -> None:
    """``--sensors rgbd``: no laser; its scan, made from depth, spans the camera's view."""
    log = camera_only_agent
    topics = [f"/robot_0/{name}" for name in ("localisation", "nav_status", "scan")]
    async with websockets.connect(
        daphne_server.rosbridge_url(), additional_headers=handshake
    ) as ws:
        operator = Operator(ws)
        await operator.subscribe(*topics)
        localised = lambda: state_of(operator.latest.get(topics[0])).get("state") == "localised"  # noqa: E731
        await operator.until(localised, LOCALISED_WITHIN, log)
        await operator.publish("/robot_0/goal", pose(CORRIDOR_A, *CAMERA_ONLY_GOAL))

        def last_status() -> int | None:
            entries = operator.latest.get(topics[1], {}).get("status_list", [])
            return entries[-1]["status"] if entries else None

        # At load 25 the robot's simulation ran at a fifth of real time: minutes of wall time.
        done = lambda: last_status() in (SUCCEEDED, ABORTED, REJECTED)  # noqa: E731
        await operator.until(done, 300, log)
    assert last_status() == SUCCEEDED, operator.latest[topics[1]]
    scan = operator.latest[topics[2]]
    assert scan["header"]["frame_id"] == "camera_depth_frame"
    assert 1.0 < scan["angle_max"] - scan["angle_min"] < 1.2  # the camera's 63 degrees
