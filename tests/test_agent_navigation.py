"""One simulated robot stepped by hand in the demo building, its bundles served by the real
application in-process: teleop, goals across sub-maps, cancelling, avoiding obstacles.

Ground truth (``hardware.true_pose``, ``body.bumped``) is read here only to judge the
robot; the robot itself never reads it.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import httpx
import numpy as np
import pytest

from cloudnav_core.messages import GoalStatus
from cloudnav_core.params import RobotConfig
from robots.agent.robot import PoseTracker, Robot, particle_filter
from robots.agent.sim.hardware import SimHardware
from robots.agent.sim.world import Box, Cylinder, World, demo_world
from robots.agent.supervisor.bundle_cache import BundleCache
from robots.agent.supervisor.maps_supervisor import MapsSupervisor

pytestmark = pytest.mark.django_db(transaction=True)

CORRIDOR_A = "boccioni_1/CorridorA"
LIMITS = (0.5, 1.5)  # the simulated body's linear and angular limits


class Recorder:
    """Stands in for the rosbridge client: keeps what the robot publishes."""

    def __init__(self) -> None:
        self.sent: list[tuple[str, dict[str, Any]]] = []

    async def publish(self, topic: str, msg: dict[str, Any]) -> bool:
        self.sent.append((topic, msg))
        return True

    def on(self, topic: str) -> list[dict[str, Any]]:
        return [msg for name, msg in self.sent if name == topic]


def make_robot(
    cloud: httpx.AsyncClient, pose: tuple[float, float, float], world: World | None = None
) -> tuple[Robot, Recorder]:
    hardware = SimHardware(world or demo_world(), pose, seed=3)
    tracker = PoseTracker(particle_filter(300, seed=3))
    supervisor = MapsSupervisor(BundleCache(cloud), tracker)
    recorder = Recorder()
    return Robot(hardware, supervisor, tracker, recorder, RobotConfig(camera_rate=0)), recorder


async def run_until(robot: Robot, done: Callable[[], bool], seconds: float) -> None:
    """Tick until ``done`` or ``seconds`` more of simulated time; fail on the latter."""
    limit = robot.seconds + seconds
    while not done():
        assert robot.seconds < limit, f"not done after {seconds} s: {robot.navigator.board}"
        await robot.tick()
        await robot.settle()


async def run_for(robot: Robot, seconds: float) -> None:
    limit = robot.seconds + seconds
    while robot.seconds < limit - 1e-9:
        await robot.tick()
        await robot.settle()


def pose_message(map_id: str, pose: tuple[float, float, float]) -> dict[str, Any]:
    x, y, yaw = pose
    return {
        "header": {"frame_id": map_id},
        "pose": {
            "position": {"x": x, "y": y, "z": 0.0},
            "orientation": {"x": 0.0, "y": 0.0, "z": math.sin(yaw / 2), "w": math.cos(yaw / 2)},
        },
    }


async def localised(robot: Robot, map_id: str) -> None:
    """Give the robot its true pose as an operator's initial pose in ``map_id``."""
    covariance = np.diag([0.02**2, 0.02**2, 0, 0, 0, 0.02**2]).ravel().tolist()
    pose = pose_message(map_id, robot.hardware.true_pose)
    robot.on_initial_pose(
        {"header": pose["header"], "pose": {"pose": pose["pose"], "covariance": covariance}}
    )
    await robot.settle()
    assert robot.supervisor.current is not None


def statuses(robot: Robot) -> list[GoalStatus]:
    return [entry.status for entry in robot.navigator.board.entries]


def twist(linear: float, angular: float) -> dict[str, Any]:
    return {"linear": {"x": linear, "y": 0, "z": 0}, "angular": {"x": 0, "y": 0, "z": angular}}


def finished(robot: Robot) -> bool:
    return robot.navigator.board.active is None


# --- teleop ----------------------------------------------------------------------------


async def test_teleop_drives_clamped_to_the_limits_and_stops_half_a_second_after(cloud):
    robot, _ = make_robot(cloud, (8.0, 23.2, 0.0))
    start = robot.hardware.true_pose
    for _ in range(20):  # 2 s of commands at 10 Hz, far beyond the limits
        robot.on_cmd_vel(twist(3.0, 4.0))
        await run_for(robot, 0.1)
        linear, angular = robot.hardware.body.velocity
        assert linear <= LIMITS[0] + 1e-9
        assert abs(angular) <= LIMITS[1] + 1e-9
    assert robot.hardware.body.velocity == pytest.approx(LIMITS)
    assert math.dist(robot.hardware.true_pose[:2], start[:2]) > 0.3

    await run_for(robot, 0.4)  # still within the watchdog's half second
    assert robot.hardware.body.velocity[0] > 0
    await run_for(robot, 0.7)  # stopped by itself, braking at its limits
    assert robot.hardware.body.velocity == (0.0, 0.0)


async def test_teleop_takes_over_from_navigation_while_it_drives(cloud):
    robot, _ = make_robot(cloud, (8.0, 23.2, 0.0))
    await localised(robot, CORRIDOR_A)
    robot.on_goal(pose_message(CORRIDOR_A, (14.0, 23.2, 0.0)))
    await run_for(robot, 2.0)
    for _ in range(10):  # the operator turns it round on the spot
        robot.on_cmd_vel(twist(0.0, -1.0))
        await run_for(robot, 0.1)
    assert robot.hardware.body.velocity[0] == pytest.approx(0.0, abs=0.05)
    await run_until(robot, lambda: finished(robot), 60)  # then navigation resumes
    assert statuses(robot) == [GoalStatus.SUCCEEDED]


# --- goals -----------------------------------------------------------------------------


async def test_a_goal_in_another_sub_map_is_routed_through_the_tag(cloud):
    robot, recorder = make_robot(cloud, (13.0, 23.2, 0.0))
    await localised(robot, CORRIDOR_A)
    goal = (22.0, 25.5, math.pi / 2)
    robot.on_goal(pose_message("boccioni_1/Atrium1", goal))
    await run_until(robot, lambda: finished(robot), 120)

    assert statuses(robot) == [GoalStatus.SUCCEEDED]
    assert robot.supervisor.current is not None
    assert robot.supervisor.current.map_id == "boccioni_1/Atrium1"
    assert math.dist(robot.hardware.true_pose[:2], goal[:2]) < 0.25
    assert [m["data"] for m in recorder.on("map_id")] == [
        f"{CORRIDOR_A}@v1",
        "boccioni_1/Atrium1@v1",
    ]
    texts = {e["text"] for m in recorder.on("nav_status") for e in m["status_list"]}
    assert "to tag 1, leading to Atrium1" in texts  # the tag the route leads through
    assert recorder.on("plan")[-1]["header"]["frame_id"] == "boccioni_1/Atrium1"
    assert recorder.on("pose")[-1]["header"]["frame_id"] == "boccioni_1/Atrium1"


async def test_a_robot_with_no_map_reads_the_tag_before_it_then_drives_on(cloud):
    from maps.domain.demo_building import demo_building

    robot, recorder = make_robot(cloud, demo_building().start_pose)
    robot.on_goal(pose_message(CORRIDOR_A, (6.0, 23.2, 0.0)))
    await run_until(robot, lambda: finished(robot), 60)

    assert statuses(robot) == [GoalStatus.SUCCEEDED]
    assert [m["data"] for m in recorder.on("map_id")] == [f"{CORRIDOR_A}@v1"]
    assert math.dist(robot.hardware.true_pose[:2], (6.0, 23.2)) < 0.25


async def test_cancelling_preempts_the_goal_and_stops_the_robot(cloud):
    robot, recorder = make_robot(cloud, (8.0, 23.2, 0.0))
    await localised(robot, CORRIDOR_A)
    robot.on_goal(pose_message(CORRIDOR_A, (16.0, 23.2, 0.0)))
    await run_for(robot, 3.0)
    assert robot.hardware.body.velocity[0] > 0.2

    assert robot.on_cancel({}) == {"success": True, "message": "cancelled"}
    await run_for(robot, 1.5)
    assert robot.hardware.body.velocity == (0.0, 0.0)
    last = recorder.on("nav_status")[-1]["status_list"][-1]
    assert last["status"] == GoalStatus.PREEMPTED
    assert last["goal_id"]["id"] == "goal_1"
    assert robot.on_cancel({})["success"] is False  # nothing left to cancel


async def test_a_new_goal_preempts_the_active_one(cloud):
    robot, _ = make_robot(cloud, (8.0, 23.2, 0.0))
    await localised(robot, CORRIDOR_A)
    robot.on_goal(pose_message(CORRIDOR_A, (16.0, 23.2, 0.0)))
    await run_for(robot, 1.0)
    robot.on_goal(pose_message(CORRIDOR_A, (7.0, 23.2, math.pi)))
    await run_until(robot, lambda: finished(robot), 60)
    assert statuses(robot) == [GoalStatus.PREEMPTED, GoalStatus.SUCCEEDED]


async def test_a_goal_in_a_sub_map_the_building_lacks_is_aborted(cloud):
    robot, _ = make_robot(cloud, (8.0, 23.2, 0.0))
    await localised(robot, CORRIDOR_A)
    robot.on_goal(pose_message("boccioni_1/Kitchen", (1.0, 1.0, 0.0)))
    await run_for(robot, 0.2)
    assert statuses(robot) == [GoalStatus.ABORTED]
    assert "Kitchen" in robot.navigator.board.entries[-1].text


@pytest.mark.parametrize("frame", [None, "", "   "])
async def test_a_goal_that_names_no_sub_map_is_rejected_saying_why(cloud, frame):
    # What a page sent when no sub-map was shown: a frame of null.
    robot, recorder = make_robot(cloud, (8.0, 23.2, 0.0))
    await localised(robot, CORRIDOR_A)
    goal = pose_message(CORRIDOR_A, (16.0, 23.2, 0.0))
    goal["header"]["frame_id"] = frame
    robot.on_goal(goal)
    await run_for(robot, 0.2)
    assert statuses(robot) == [GoalStatus.REJECTED]
    last = recorder.on("nav_status")[-1]["status_list"][-1]
    assert last["status"] == GoalStatus.REJECTED
    assert "names no sub-map" in last["text"]
    assert "frame_id" in last["text"]
    assert robot.hardware.body.velocity == (0.0, 0.0)


async def test_a_goal_without_a_usable_pose_is_rejected_saying_why(cloud):
    robot, _ = make_robot(cloud, (8.0, 23.2, 0.0))
    robot.on_goal({"header": {"frame_id": CORRIDOR_A}, "pose": {"position": {"x": "far"}}})
    assert statuses(robot) == [GoalStatus.REJECTED]
    assert "no usable pose" in robot.navigator.board.entries[-1].text


async def test_every_goal_that_ends_badly_says_why(cloud):
    robot, recorder = make_robot(cloud, (8.0, 23.2, 0.0))
    await localised(robot, CORRIDOR_A)
    robot.on_goal(pose_message("Kitchen", (1.0, 1.0, 0.0)))  # a bare code: this building's
    robot.on_goal(pose_message("boccioni_1/CorridorA", (0.0, 0.0, 0.0)))  # in a wall
    await run_for(robot, 1.0)
    ended = [e for m in recorder.on("nav_status") for e in m["status_list"] if e["status"] > 1]
    assert {e["status"] for e in ended} >= {GoalStatus.ABORTED}
    assert all(e["text"] for e in ended)


async def test_a_robot_says_it_is_lost_until_an_initial_pose_places_it(cloud):
    robot, recorder = make_robot(cloud, (10.0, 23.2, 0.0))  # mid Corridor A, no tag in reach
    await run_for(robot, 1.0)
    [lost] = recorder.on("localisation")[:1]
    assert (lost["level"], lost["message"]) == (1, "lost, looking for a tag")
    assert {"key": "state", "value": "lost"} in lost["values"]
    await localised(robot, CORRIDOR_A)
    await run_for(robot, 0.2)
    now = recorder.on("localisation")[-1]
    assert now["level"] == 0
    assert now["message"] == f"localised in {CORRIDOR_A} by initial pose"


async def test_a_robot_before_a_tag_says_it_read_it_and_is_localised(cloud):
    from maps.domain.demo_building import demo_building

    robot, recorder = make_robot(cloud, demo_building().robot_starts[0])
    await run_until(robot, lambda: robot.supervisor.current is not None, 5)
    await run_for(robot, 0.2)
    states = [m["message"] for m in recorder.on("localisation")]
    assert states[-1] == f"localised in {CORRIDOR_A} by tag 0"
    assert "lost, looking for a tag" not in states[1:]  # never lost again once it read the tag


async def test_a_lost_robot_with_no_tag_in_sight_gives_up_after_looking_round(cloud):
    robot, _ = make_robot(cloud, (22.0, 14.0, 0.0))  # mid Corridor B, tags out of range
    robot.on_goal(pose_message(CORRIDOR_A, (6.0, 23.2, 0.0)))
    await run_until(robot, lambda: finished(robot), 40)
    assert statuses(robot) == [GoalStatus.ABORTED]
    assert robot.navigator.board.entries[-1].text == "no tag in sight"


# --- obstacles -------------------------------------------------------------------------


def clearance_to(robot: Robot, obstacle: Cylinder) -> float:
    x, y, _ = robot.hardware.true_pose
    return math.hypot(x - obstacle.x, y - obstacle.y) - obstacle.radius


async def test_it_drives_round_an_obstacle_that_is_not_on_the_map(cloud):
    bin_ = Cylinder(12.0, 23.2, 0.3)  # on the corridor's centre line, on no map
    robot, _ = make_robot(cloud, (8.0, 23.2, 0.0), demo_world(obstacles=[bin_]))
    await localised(robot, CORRIDOR_A)
    robot.on_goal(pose_message(CORRIDOR_A, (16.0, 23.2, 0.0)))
    closest = math.inf
    bumped = False

    def done() -> bool:
        nonlocal closest, bumped
        closest = min(closest, clearance_to(robot, bin_))
        bumped = bumped or robot.hardware.body.bumped
        return finished(robot)

    await run_until(robot, done, 60)
    assert statuses(robot) == [GoalStatus.SUCCEEDED]
    assert not bumped
    assert closest > 0.18  # the robot's radius: it never touched the bin


async def test_it_plans_again_round_an_obstacle_that_blocks_its_way(cloud):
    # A long screen across Atrium 1, on no map: the straight plan runs into it and the
    # controller alone cannot get round; the robot must plan again around what it sees.
    screen = Box(19.0, 22.9, 24.8, 23.1)
    robot, _ = make_robot(cloud, (21.5, 25.8, -math.pi / 2), demo_world(obstacles=[screen]))
    await localised(robot, "boccioni_1/Atrium1")
    robot.on_goal(pose_message("boccioni_1/Atrium1", (21.5, 20.2, -math.pi / 2)))
    await run_until(robot, lambda: finished(robot), 120)
    assert statuses(robot) == [GoalStatus.SUCCEEDED]
    assert robot.navigator.driver.plan_version > 1
