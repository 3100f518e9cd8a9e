"""The ROS 1 navigation stack the Maps Supervisor feeds, on a real roscore (Debian's ROS 1
packages): the sub-map on the latched ``/map`` as ``rostopic echo`` sees it, the tag's
pose on ``/initialpose`` with its covariance, a goal as a ``move_base`` action goal, and
cancel preempting it. Skipped where ROS 1 is not installed (``scripts/setup.sh`` installs it)."""

from __future__ import annotations

import math
import os
import shutil
import socket
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from robots.agent.ros import ros_path

pytestmark = [
    pytest.mark.skipif(
        not ros_path() or shutil.which("roscore") is None, reason="ROS 1 (ros-core) not installed"
    ),
    pytest.mark.filterwarnings("ignore:notifyAll:DeprecationWarning"),
]

ROOT = Path(__file__).resolve().parent.parent
MAP_ID = "boccioni_1/CorridorA"
ACTIVE, PREEMPTED = 1, 2


def wait_for(done: Callable[[], Any], seconds: float, what: str) -> Any:
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        value = done()
        if value:
            return value
        time.sleep(0.05)
    raise AssertionError(f"timed out waiting for {what}")


def free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return int(probe.getsockname()[1])


@pytest.fixture(scope="session")
def ros_env(tmp_path_factory: pytest.TempPathFactory) -> Iterator[dict[str, str]]:
    """A real roscore on a free port; the environment that reaches it."""
    port = free_port()
    env = dict(os.environ)
    env.update(
        ROS_MASTER_URI=f"http://127.0.0.1:{port}",
        ROS_HOSTNAME="127.0.0.1",
        ROS_HOME=str(tmp_path_factory.mktemp("ros_home")),
    )
    env.pop("PYTHONPATH", None)
    core = subprocess.Popen(
        ["roscore", "-p", str(port)],
        env=env,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        start_new_session=True,
    )
    try:
        import rosgraph  # type: ignore[import-not-found,unused-ignore]

        master = rosgraph.Master("/probe", master_uri=env["ROS_MASTER_URI"])
        wait_for(lambda: _online(master), 60, "roscore")
        yield env
    finally:
        core.terminate()
        core.wait(timeout=30)


def _online(master: Any) -> bool:
    try:
        master.getPid()
    except Exception:
        return False
    return True


@pytest.fixture(scope="session")
def node(ros_env: dict[str, str]) -> Iterator[None]:
    for name in ("ROS_MASTER_URI", "ROS_HOSTNAME", "ROS_HOME"):
        os.environ[name] = ros_env[name]
    import rospy  # type: ignore[import-not-found,unused-ignore]

    rospy.init_node("cloudnav_bridge_test", anonymous=True, disable_signals=True)
    yield
    rospy.signal_shutdown("test done")


def test_maps_poses_goals_and_cancel_reach_ros(
    node: None, ros_env: dict[str, str], tmp_path: Path
) -> None:
    import actionlib  # type: ignore[import-not-found,unused-ignore]
    import rospy  # type: ignore[import-not-found,unused-ignore]
    from geometry_msgs.msg import (  # type: ignore[import-not-found,unused-ignore]
        PoseWithCovarianceStamped,
    )
    from move_base_msgs.msg import MoveBaseAction  # type: ignore[import-not-found,unused-ignore]

    from robots.agent.ros.navigation import RosNavigationStack

    # A minimal move_base: holds each goal active until it is preempted.
    goals: list[Any] = []

    def execute(goal: Any) -> None:
        goals.append(goal)
        while not rospy.is_shutdown():
            if server.is_preempt_requested():
                server.set_preempted()
                return
            time.sleep(0.02)

    server = actionlib.SimpleActionServer("move_base", MoveBaseAction, execute, auto_start=False)
    server.start()
    poses: list[Any] = []
    rospy.Subscriber("/initialpose", PoseWithCovarianceStamped, poses.append)

    stack = RosNavigationStack()
    assert stack.wait_for_server(30)
    grid = np.zeros((30, 40), dtype=np.int8)
    grid[0, :] = 100
    grid[-1, -1] = -1
    stack.set_map(MAP_ID, grid, 0.05, (1.0, 2.0, 0.0))

    # Latched: a subscriber that arrives afterwards still gets it.
    echoed = subprocess.run(
        ["rostopic", "echo", "-n", "1", "/map/info"],
        env=ros_env,
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert echoed.returncode == 0, echoed.stderr
    assert "width: 40" in echoed.stdout
    assert "height: 30" in echoed.stdout
    assert "resolution: 0.05" in echoed.stdout

    covariance = np.diag([0.04, 0.09, 0.01])
    stack.set_initial_pose(MAP_ID, (1.5, 2.5, 0.3), covariance)
    initial = wait_for(lambda: poses, 30, "/initialpose")[0]
    assert initial.header.frame_id == "map"
    assert initial.pose.pose.position.x == pytest.approx(1.5)
    assert initial.pose.covariance[0] == pytest.approx(0.04)
    assert initial.pose.covariance[7] == pytest.approx(0.09)
    assert initial.pose.covariance[35] == pytest.approx(0.01)

    with pytest.raises(ValueError, match="not the map"):
        stack.send_goal("boccioni_1/Other", (0.0, 0.0, 0.0))
    stack.send_goal(MAP_ID, (3.0, 4.0, 1.0))
    goal = wait_for(lambda: goals, 30, "the move_base goal")[0]
    assert goal.target_pose.header.frame_id == "map"
    assert goal.target_pose.pose.position.x == pytest.approx(3.0)
    assert goal.target_pose.pose.position.y == pytest.approx(4.0)
    wait_for(lambda: stack.state() == ACTIVE, 30, "an active goal")

    stack.cancel()
    wait_for(lambda: stack.state() == PREEMPTED, 30, "the goal preempted")


def test_a_ros_robot_is_the_softwares_hardware(node: None) -> None:
    import cv2
    import rospy  # type: ignore[import-not-found,unused-ignore]
    from geometry_msgs.msg import Twist  # type: ignore[import-not-found,unused-ignore]
    from nav_msgs.msg import Odometry  # type: ignore[import-not-found,unused-ignore]
    from sensor_msgs.msg import (  # type: ignore[import-not-found,unused-ignore]
        CompressedImage,
        LaserScan,
    )

    from robots.agent.hardware import Hardware
    from robots.agent.ros.hardware import RosHardware

    # The robot's drivers, latched so the hardware finds their last message.
    odom = Odometry()
    odom.header.frame_id, odom.child_frame_id = "odom", "base_footprint"
    odom.pose.pose.position.x, odom.pose.pose.position.y = 1.0, 2.0
    odom.pose.pose.orientation.z, odom.pose.pose.orientation.w = math.sin(0.25), math.cos(0.25)
    odom.pose.covariance = [0.01 * (i % 7 == 0) for i in range(36)]
    odom.twist.twist.linear.x, odom.twist.twist.angular.z = 0.3, -0.1
    scan = LaserScan()
    scan.header.frame_id = "base_scan"
    scan.angle_min, scan.angle_increment = -math.pi / 2, math.pi / 180
    scan.angle_max = scan.angle_min + 180 * scan.angle_increment
    scan.range_min, scan.range_max = 0.1, 10.0
    scan.ranges = [2.0] * 90 + [math.inf] * 91
    frame = np.zeros((480, 640), dtype=np.uint8)
    frame[100:200, 300:400] = 255
    image = CompressedImage()
    image.format, image.data = "jpeg", cv2.imencode(".jpg", frame)[1].tobytes()
    for topic, kind, msg in (
        ("/odom", Odometry, odom),
        ("/scan", LaserScan, scan),
        ("/camera/image/compressed", CompressedImage, image),
    ):
        rospy.Publisher(topic, kind, queue_size=1, latch=True).publish(msg)
    commands: list[Any] = []
    rospy.Subscriber("/cmd_vel", Twist, commands.append)

    hardware: Hardware = RosHardware(timeout=30)
    assert hardware.odom_pose == pytest.approx((1.0, 2.0, 0.5))
    assert hardware.reported_velocity == pytest.approx((0.3, -0.1))
    ranges = hardware.scan()
    assert ranges.shape == hardware.scan_angles.shape == (181,)
    assert hardware.scan_angles[90] == pytest.approx(0.0, abs=1e-6)
    message = hardware.scan_message(ranges, 12.5)
    assert message["ranges"][0] == pytest.approx(2.0)
    assert message["ranges"][-1] is None
    assert hardware.odometry_message(12.5)["pose"]["covariance"][0] == pytest.approx(0.01)
    seen = wait_for(lambda: hardware.image()[150, 350] > 200, 30, "the camera frame")
    assert seen

    def commanded() -> bool:
        hardware.command(0.2, 0.4)  # until the subscriber has connected
        return bool(commands)

    wait_for(commanded, 30, "cmd_vel")
    assert (commands[-1].linear.x, commands[-1].angular.z) == pytest.approx((0.2, 0.4))


ROBOT = "robot_0"
CORRIDOR_A = "boccioni_1/CorridorA"
START = (8.0, 23.2, 0.0)


def start_bridge(ros_env: dict[str, str], server: str, token: str) -> subprocess.Popen[str]:
    """``python -m robots.agent.ros`` for ``robot_0``, as a robot would run it."""
    return subprocess.Popen(
        [
            *(sys.executable, "-m", "robots.agent.ros", "--server", server, "--token", token),
            *("--particles", "0", "--node", "cloudnav_bridge_robot_0"),
        ],
        env={**ros_env, "PYTHONPATH": str(ROOT)},
        cwd=ROOT,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        text=True,
    )


@pytest.mark.slow
async def test_the_bridge_node_carries_an_operators_goal_to_ros_and_survives_the_cloud(
    node: None, ros_env: dict[str, str], daphne_server: Any, demo_token: str, operator_headers: Any
) -> None:
    import rospy  # type: ignore[import-not-found,unused-ignore]
    import websockets
    from geometry_msgs.msg import Twist  # type: ignore[import-not-found,unused-ignore]
    from nav_msgs.msg import Odometry  # type: ignore[import-not-found,unused-ignore]
    from sensor_msgs.msg import LaserScan  # type: ignore[import-not-found,unused-ignore]

    from tests.test_agent_live import Operator, pose, with_covariance

    # The robot's drivers: a base standing still and a laser seeing open space.
    odom = Odometry()
    odom.header.frame_id, odom.child_frame_id = "odom", "base_footprint"
    odom.pose.pose.orientation.w = 1.0
    scan = LaserScan()
    scan.header.frame_id = "base_scan"
    scan.angle_min, scan.angle_increment = -math.pi / 2, math.pi / 180
    scan.angle_max, scan.range_min, scan.range_max = math.pi / 2, 0.1, 10.0
    scan.ranges = [5.0] * 181
    odom_out = rospy.Publisher("/odom", Odometry, queue_size=1, latch=True)
    scan_out = rospy.Publisher("/scan", LaserScan, queue_size=1, latch=True)
    odom_out.publish(odom)
    scan_out.publish(scan)
    commands: list[tuple[float, float, float]] = []
    rospy.Subscriber(
        "/cmd_vel",
        Twist,
        lambda t: commands.append((time.monotonic(), t.linear.x, t.angular.z)),
    )

    bridge = start_bridge(ros_env, daphne_server.url, demo_token)
    try:
        async with websockets.connect(
            daphne_server.rosbridge_url(), additional_headers=operator_headers
        ) as ws:
            operator = Operator(ws)
            for topic in ("pose", "nav_status", "map_id", "odom"):
                await operator.send(op="subscribe", topic=f"/{ROBOT}/{topic}")
            await operator.until(lambda: f"/{ROBOT}/odom" in operator.latest, "the bridge", 90)

            placed = with_covariance(pose(CORRIDOR_A, *START))
            await operator.send(op="publish", topic=f"/{ROBOT}/initialpose", msg=placed)
            await operator.until(lambda: f"/{ROBOT}/pose" in operator.latest, "a pose", 60)
            entered = operator.latest[f"/{ROBOT}/map_id"]["data"]
            assert entered.split("@")[0] == CORRIDOR_A  # "@v1": the map's version

            goal = pose(CORRIDOR_A, 16, 23.2, 0)
            await operator.send(op="publish", topic=f"/{ROBOT}/goal", msg=goal)
            await operator.until(lambda: operator.last_status() == ACTIVE, "the goal taken", 60)
            await operator.until(lambda: any(c[1] > 0.05 for c in commands), "cmd_vel on ROS")
            answer = await operator.call(f"/{ROBOT}/cancel_goal", {}, "cancel")
            assert answer["result"] is True
            await operator.until(lambda: operator.last_status() == PREEMPTED, "PREEMPTED")

            await operator.send(op="publish", topic=f"/{ROBOT}/goal", msg=goal)
            await operator.until(lambda: operator.last_status() == ACTIVE, "the goal again", 60)

        daphne_server.stop()  # the cloud goes away: the robot drives on its held map
        cut = time.monotonic()
        wait_for(
            lambda: any(t > cut + 2 and linear > 0.05 for t, linear, _ in commands),
            30,
            "cmd_vel after the cloud went away",
        )
        assert bridge.poll() is None
    finally:
        bridge.terminate()
        try:
            bridge.wait(timeout=30)
        except subprocess.TimeoutExpired:
            bridge.kill()
            bridge.wait(timeout=30)
