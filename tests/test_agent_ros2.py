"""A ROS 2 robot on stock rclpy (Jazzy and Kilted, the pinned wheels in their own
virtualenv that ``scripts/ros2_env.sh`` builds and caches), its Nav2 stand-in, the bridge
(``python -m robots.agent.ros2``) and a live CloudNav server.

The robot is rclpy nodes (``robots.agent.sim.ros2_robot``): the simulator's body, laser and
camera with tf and ``CameraInfo``; an AMCL stand-in on ``/amcl_pose``; a ``NavigateToPose``
server that drives it; map_server's ``LoadMap``; and a separate transient-local ``/map``
subscriber. They report what they see as JSON lines (this process has no rclpy). Each test
has its own ``ROS_DOMAIN_ID``, with discovery kept on this machine. A missing wheel or a
failed build fails the test: nothing here is skipped.
"""

from __future__ import annotations

import itertools
import json
import math
import subprocess
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from benchmarks import ros2_bridge
from benchmarks.ros_bridge import start_node, stop_node
from tests.fixtures_live import wait_for, worker_index
from tests.support.agent_operator import ACTIVE, CORRIDOR_A, ROBOT, Operator, pose
from tests.support.ros_robot import (
    ATRIUM_1,
    BACK_IN_CORRIDOR_A,
    IN_ATRIUM_1,
    SUB_MAP_SIZES,
    SUCCEEDED,
    TAG_1_APPROACH,
    TURNING,
    cloud_grid,
    log_tails,
)

TELEOP_HOLD = 0.5  # robots.agent.robot.TELEOP_HOLD: the dead-man's delay
DOMAINS_PER_WORKER = 25
_domains = itertools.count()


@pytest.fixture
def ros2_env(ros2_venv: Path) -> dict[str, str]:
    """The environment of this test's ROS 2 graph: its own domain (apart from those of
    other pytest workers), on this machine only."""
    domain = 1 + worker_index() * DOMAINS_PER_WORKER + next(_domains) % DOMAINS_PER_WORKER
    return ros2_bridge.graph_env(ros2_venv, domain)


class Events:
    """The JSON lines a node of the simulated robot writes (``ros2_nodes.Events``)."""

    def __init__(self, path: Path) -> None:
        self.path = path
        path.touch()

    def all(self, event: str, since: float = 0.0) -> list[dict[str, Any]]:
        lines = self.path.read_text().splitlines()
        found = (json.loads(line) for line in lines if line.endswith("}"))
        return [e for e in found if e["event"] == event and e["t"] >= since]


class Ros2Robot:
    """The simulated robot's processes and what they report."""

    def __init__(self, env: dict[str, str], tmp_path: Path, cloud: str) -> None:
        self.env, self.tmp_path = env, tmp_path
        self.processes: list[subprocess.Popen[bytes]] = []
        self.body = self._node("body", "--cloud", cloud)
        self.nav2 = self._node("nav2")
        self.watch = self._node("watch")

    def _node(self, name: str, *args: str) -> Events:
        events = Events(self.tmp_path / f"{name}.jsonl")
        command = ("robots.agent.sim.ros2_robot", name, "--events", str(events.path), *args)
        self.processes.append(self.start(name, *command))
        return events

    def start(self, log: str, *command: str) -> subprocess.Popen[bytes]:
        """``python -m <command>`` in the ROS 2 virtualenv (its ``python`` first on the
        environment's PATH), its output in ``log.log``."""
        return start_node(self.env, self.tmp_path / f"{log}.log", *command, python="python")

    def logs(self) -> str:
        return log_tails(self.tmp_path)

    def goal_near(self, x: float, y: float, since: float = 0.0) -> bool:
        return any(math.dist((g["x"], g["y"]), (x, y)) < 0.05 for g in self.nav2.all("goal", since))

    def succeeded_since(self, since: float) -> bool:
        return any(r["status"] == 4 for r in self.nav2.all("result", since))  # STATUS_SUCCEEDED

    def bridge_commands(self) -> list[dict[str, Any]]:
        """The bridge's ``cmd_vel`` (the Nav2 stand-in's go to ``cmd_vel_nav``)."""
        return [c for c in self.body.all("cmd_vel") if c["topic"] == "cmd_vel"]

    def watched_map(self) -> dict[str, Any] | None:
        maps = self.watch.all("map")
        return maps[-1] if maps else None

    def stop(self) -> None:
        for process in self.processes:
            stop_node(process)


@pytest.fixture
def ros2_robot(ros2_env: dict[str, str], tmp_path: Path, daphne_server: Any) -> Iterator[Ros2Robot]:
    robot = Ros2Robot(ros2_env, tmp_path, daphne_server.url)
    yield robot
    robot.stop()


@pytest.mark.slow
@pytest.mark.timeout(1500)
async def test_a_ros2_robot_crosses_sub_maps_through_nav2_and_stops_when_the_cloud_goes(
    ros2_robot: Ros2Robot,
    daphne_server: Any,
    demo_token: str,
    operator_headers: Any,
    tmp_path: Path,
) -> None:
    import websockets

    ros = ros2_robot
    bridge = ros.start(
        "bridge",
        *("robots.agent.ros2", "--server", daphne_server.url, "--token", demo_token),
        *("--load-map", "/map_server/load_map", "--map-dir", str(tmp_path / "maps")),
        *("--node", "cloudnav_bridge_robot_0"),
    )
    ros.processes.append(bridge)
    try:
        async with websockets.connect(
            daphne_server.rosbridge_url(), additional_headers=operator_headers
        ) as ws:
            operator = Operator(ws)
            await operator.watch("pose", "nav_status", "map_id", "plan")

            # Standing before the entrance tag, the robot reads it: Corridor A on /map,
            # cell for cell, as a separate transient-local subscriber reads it.
            await operator.until(
                lambda: operator.entered(CORRIDOR_A), f"Corridor A\n{ros.logs()}", 180
            )
            seen = wait_for(ros.watched_map, 60, "/map")
            assert (seen["width"], seen["height"]) == SUB_MAP_SIZES[CORRIDOR_A]
            grid = np.asarray(seen["cells"], dtype=np.int8).reshape(seen["height"], seen["width"])
            assert np.array_equal(grid, await cloud_grid(daphne_server, demo_token, CORRIDOR_A))
            placed = wait_for(lambda: ros.nav2.all("initial_pose"), 30, "/initialpose")[-1]
            assert placed["xx"] > 0  # the tag's covariance, not zeros
            loaded = wait_for(lambda: ros.nav2.all("load_map"), 30, "LoadMap")
            assert loaded[-1]["url"].endswith("boccioni_1__CorridorA.yaml")

            # The operator's goal in Atrium 1 reaches Nav2 as a NavigateToPose goal to tag 1
            # first; Nav2's feedback reaches the cloud; cancel cancels the Nav2 goal.
            sent = time.monotonic()
            goal = pose(ATRIUM_1, *IN_ATRIUM_1)
            await operator.send_goal(goal)
            await operator.until(
                lambda: ros.goal_near(*TAG_1_APPROACH, since=sent), f"a goal\n{ros.logs()}", 60
            )
            await operator.until(lambda: operator.last_status() == ACTIVE, "ACTIVE", 30)
            await operator.until(lambda: "m to go" in operator.status_text(), "Nav2's feedback", 60)
            await operator.cancel_goal()
            wait_for(lambda: ros.nav2.all("cancel", sent), 30, "the Nav2 goal cancelled")

            # Sent again, it crosses into Atrium 1 by reading tag 1 (LoadMap called with
            # Atrium 1's files), and the goal succeeds.
            await operator.send_goal(goal)
            await operator.until(lambda: f"/{ROBOT}/plan" in operator.latest, "a plan", 60)
            await operator.until(lambda: operator.entered(ATRIUM_1), f"Atrium 1\n{ros.logs()}", 480)
            wait_for(
                lambda: (ros.watched_map() or {}).get("width") == SUB_MAP_SIZES[ATRIUM_1][0],
                30,
                "Atrium 1 on /map",
            )
            wait_for(
                lambda: ros.nav2.all("load_map")[-1]["url"].endswith("boccioni_1__Atrium1.yaml"),
                30,
                "LoadMap of Atrium 1",
            )
            await operator.until(
                lambda: operator.last_status() == SUCCEEDED, f"SUCCEEDED\n{ros.logs()}", 360
            )
            assert operator.distance_to(IN_ATRIUM_1) < 0.5

            # Back to Corridor A; teleop meanwhile, and the cloud goes away mid-teleop.
            back = pose(CORRIDOR_A, *BACK_IN_CORRIDOR_A)
            await operator.send_goal(back)
            await operator.until(lambda: operator.last_status() == ACTIVE, "ACTIVE again", 30)

            def turning() -> list[float]:
                turns = ros.bridge_commands()
                return [c["t"] for c in turns if c["angular"] == pytest.approx(TURNING)]

            await operator.teleop_until(turning, TURNING)
            # Teleop has held the goal: the robot sends it again only after its last command
            # (on a slow machine it may have read tag 2 before the teleop began).
            teleop_ended = time.monotonic()
        daphne_server.stop()
        cut = time.monotonic()

        # The dead-man rule on the robot itself: its last teleop command is followed by a
        # stop within TELEOP_HOLD (and control periods that a loaded machine stretches),
        # though no cloud can send one. The last command left the server before its end
        # (one in flight as the operator stopped may land just before it), so the stop
        # follows the end within the same hold and control periods.
        stop = wait_for(lambda: stopped_after(ros.bridge_commands(), turning()[-1]), 30, "stop")
        assert stop - turning()[-1] <= TELEOP_HOLD + 0.5
        assert stop <= cut + TELEOP_HOLD + 0.5
        # Then it drives on with its held maps: tag 2 read, Corridor A on /map again, and
        # Nav2 takes it to the goal with no cloud at all.
        wait_for(
            lambda: ros.goal_near(*BACK_IN_CORRIDOR_A[:2], since=teleop_ended),
            480,
            f"goal\n{ros.logs()}",
        )
        assert (ros.watched_map() or {}).get("width") == SUB_MAP_SIZES[CORRIDOR_A][0]
        wait_for(lambda: ros.succeeded_since(teleop_ended), 360, f"arrived offline\n{ros.logs()}")
        assert all(p.poll() is None for p in ros.processes), ros.logs()
    finally:
        stop_node(bridge)


def stopped_after(commands: list[dict[str, Any]], since: float) -> float | None:
    """When the first zero ``cmd_vel`` after ``since`` came; None before one has."""
    stops = [c["t"] for c in commands if c["t"] > since and c["linear"] == c["angular"] == 0.0]
    return stops[0] if stops else None
