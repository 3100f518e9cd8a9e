"""The ROS 1 navigation stack the Maps Supervisor feeds, on a real roscore (Debian's ROS 1
packages): the sub-map on the latched ``/map`` as ``rostopic echo`` sees it, the tag's
pose on ``/initialpose`` with its covariance, a goal as a ``move_base`` action goal, and
cancel preempting it. Skipped where ROS 1 is not installed (``scripts/setup.sh`` installs it)."""

from __future__ import annotations

import math
import shutil
import subprocess
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from benchmarks.ros_bridge import start_node, stop_node
from robots.agent.ros import ros_path
from tests.fixtures_live import wait_for
from tests.support.agent_operator import ACTIVE, CORRIDOR_A, PREEMPTED, ROBOT, START, Operator, pose
from tests.support.ros_robot import (
    ATRIUM_1,
    BACK_IN_CORRIDOR_A,
    IN_ATRIUM_1,
    SUCCEEDED,
    TAG_1_APPROACH,
    TURNING,
    cloud_grid,
    log_tails,
)

pytestmark = [
    pytest.mark.skipif(
        not ros_path() or shutil.which("roscore") is None, reason="ROS 1 (ros-core) not installed"
    ),
    pytest.mark.filterwarnings("ignore:notifyAll:DeprecationWarning"),
]

MAP_ID = "boccioni_1/CorridorA"


@pytest.fixture(scope="session")
def ros_env() -> Iterator[dict[str, str]]:
    """A real roscore on a free port (this process's node reaches it too); the
    environment that reaches it."""
    from robots.agent.ros.master import private_roscore

    with private_roscore() as env:
        yield env


@pytest.fixture(scope="session")
def node(ros_env: dict[str, str]) -> Iterator[None]:
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
        PoseStamped,
        PoseWithCovarianceStamped,
    )
    from move_base_msgs.msg import MoveBaseAction  # type: ignore[import-not-found,unused-ignore]
    from nav_msgs.msg import Path as PlanPath  # type: ignore[import-not-found,unused-ignore]

    from robots.agent.hardware import StackGoal
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

    # Its names are the test's own: the session's roscore serves later tests too.
    server = actionlib.SimpleActionServer(
        "/probe/move_base", MoveBaseAction, execute, auto_start=False
    )
    server.start()
    poses: list[Any] = []
    rospy.Subscriber("/probe/initialpose", PoseWithCovarianceStamped, poses.append)

    stack = RosNavigationStack(
        map_topic="/probe/map",
        initial_pose_topic="/probe/initialpose",
        action="/probe/move_base",
        pose_source="/probe/amcl_pose",
        plan_topic="/probe/plan",
    )
    assert stack.wait_for_server(30)
    grid = np.zeros((30, 40), dtype=np.int8)
    grid[0, :] = 100
    grid[-1, -1] = -1
    stack.set_map(MAP_ID, grid, 0.05, (1.0, 2.0, 0.0))

    # Latched: a subscriber that arrives afterwards still gets it.
    echoed = subprocess.run(
        ["rostopic", "echo", "-n", "1", "/probe/map/info"],
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
    assert stack.goal_state() is StackGoal.ACTIVE

    stack.cancel()
    wait_for(lambda: stack.state() == PREEMPTED, 30, "the goal preempted")
    assert stack.goal_state() is StackGoal.NONE

    # AMCL's pose counts once stamped after the last initial pose; so does a plan.
    assert stack.pose() is None
    localised = PoseWithCovarianceStamped()
    localised.header.stamp, localised.header.frame_id = rospy.Time.now(), "map"
    localised.pose.pose.position.x, localised.pose.pose.orientation.w = 1.6, 1.0
    amcl = rospy.Publisher("/probe/amcl_pose", PoseWithCovarianceStamped, queue_size=1, latch=True)
    amcl.publish(localised)
    assert wait_for(stack.pose, 30, "the pose from amcl_pose") == pytest.approx((1.6, 0.0, 0.0))
    plan = PlanPath()
    plan.header.frame_id = "map"
    plan.poses = [PoseStamped(), PoseStamped()]
    plan.poses[1].pose.position.x = 2.0
    planner = rospy.Publisher("/probe/plan", PlanPath, queue_size=1, latch=True)
    planner.publish(plan)
    wait_for(lambda: stack.plan()[0] > 0, 30, "the plan")
    assert list(stack.plan()[1]) == [(0.0, 0.0), (2.0, 0.0)]


def test_the_pose_may_come_from_tf(node: None) -> None:
    import rospy  # type: ignore[import-not-found,unused-ignore]
    import tf2_ros  # type: ignore[import-not-found,unused-ignore]
    from geometry_msgs.msg import TransformStamped  # type: ignore[import-not-found,unused-ignore]

    from robots.agent.ros.navigation import RosNavigationStack

    stack = RosNavigationStack(
        frame="probe_tf_map",
        map_topic="/probe_tf/map",
        initial_pose_topic="/probe_tf/initialpose",
        action="/probe_tf/move_base",
        pose_source="tf",
        base_frame="probe_tf_base",
    )
    stack.set_map("b/m", np.zeros((2, 2), dtype=np.int8), 0.05, (0.0, 0.0, 0.0))
    stack.set_initial_pose("b/m", (0.0, 0.0, 0.0), np.eye(3))
    localised = TransformStamped()
    localised.header.stamp, localised.header.frame_id = rospy.Time.now(), "probe_tf_map"
    localised.child_frame_id = "probe_tf_base"
    localised.transform.translation.x, localised.transform.translation.y = 2.0, 3.0
    localised.transform.rotation.z = math.sin(0.2)
    localised.transform.rotation.w = math.cos(0.2)
    broadcaster = tf2_ros.TransformBroadcaster()

    def seen() -> Any:
        localised.header.stamp = rospy.Time.now()
        broadcaster.sendTransform(localised)
        return stack.pose()

    assert wait_for(seen, 30, "the pose from tf") == pytest.approx((2.0, 3.0, 0.4))


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
        ("/probe/odom", Odometry, odom),
        ("/probe/scan", LaserScan, scan),
        ("/probe/camera/image/compressed", CompressedImage, image),
    ):
        rospy.Publisher(topic, kind, queue_size=1, latch=True).publish(msg)
    commands: list[Any] = []
    rospy.Subscriber("/probe/cmd_vel", Twist, commands.append)

    hardware: Hardware = RosHardware(
        odom="/probe/odom",
        scan="/probe/scan",
        camera="/probe/camera/image/compressed",
        cmd_vel="/probe/cmd_vel",
        timeout=30,
    )
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


def test_the_tag_detector_uses_the_robots_camera_info(node: None) -> None:
    import rospy  # type: ignore[import-not-found,unused-ignore]
    from nav_msgs.msg import Odometry  # type: ignore[import-not-found,unused-ignore]
    from sensor_msgs.msg import (  # type: ignore[import-not-found,unused-ignore]
        CameraInfo,
        LaserScan,
    )

    from cloudnav_core.camera import CameraModel
    from robots.agent.perception import TagDetector
    from robots.agent.ros.hardware import RosHardware

    scan = LaserScan()
    scan.angle_min, scan.angle_increment, scan.ranges = 0.0, 0.1, [1.0] * 10
    info = CameraInfo()
    info.width, info.height = 1280, 720
    info.K = [910.0, 0.0, 641.5, 0.0, 905.0, 359.5, 0.0, 0.0, 1.0]
    for topic, kind, msg in (
        ("/calibrated/odom", Odometry, Odometry()),
        ("/calibrated/scan", LaserScan, scan),
        ("/calibrated/camera/camera_info", CameraInfo, info),
    ):
        rospy.Publisher(topic, kind, queue_size=1, latch=True).publish(msg)

    def hardware(namespace: str) -> RosHardware:
        return RosHardware(
            odom="/calibrated/odom",
            scan="/calibrated/scan",
            camera=f"/{namespace}/camera/image/compressed",
            camera_info=f"/{namespace}/camera/camera_info",
            cmd_vel=f"/{namespace}/cmd_vel",
            timeout=30,
            calibration_wait=10 if namespace == "calibrated" else 0.5,
        )

    calibrated = hardware("calibrated").camera_model
    assert (calibrated.width, calibrated.height) == (1280, 720)
    detector = TagDetector(calibrated)  # as the robot's software builds it from the hardware
    assert detector.camera.matrix() == pytest.approx(np.reshape(info.K, (3, 3)))
    assert hardware("uncalibrated").camera_model == CameraModel()


def start_bridge(ros_env: dict[str, str], log: Path, server: str, token: str) -> Any:
    """``python -m robots.agent.ros`` for ``robot_0``, as a robot would run it."""
    return start_node(
        ros_env,
        log,
        *("robots.agent.ros", "--server", server, "--token", token),
        *("--particles", "0", "--node", "cloudnav_bridge_robot_0", "--navigation", "agent"),
    )


@pytest.mark.slow
async def test_the_bridge_node_carries_an_operators_goal_to_ros_and_survives_the_cloud(
    node: None,
    ros_env: dict[str, str],
    daphne_server: Any,
    demo_token: str,
    operator_headers: Any,
    tmp_path: Path,
) -> None:
    import rospy  # type: ignore[import-not-found,unused-ignore]
    import websockets
    from geometry_msgs.msg import Twist  # type: ignore[import-not-found,unused-ignore]
    from nav_msgs.msg import Odometry  # type: ignore[import-not-found,unused-ignore]
    from sensor_msgs.msg import LaserScan  # type: ignore[import-not-found,unused-ignore]

    from tests.support.agent_operator import with_covariance

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

    bridge = start_bridge(ros_env, tmp_path / "bridge.log", daphne_server.url, demo_token)
    try:
        async with websockets.connect(
            daphne_server.rosbridge_url(), additional_headers=operator_headers
        ) as ws:
            operator = Operator(ws)
            await operator.watch("pose", "nav_status", "map_id", "odom")
            await operator.until(lambda: f"/{ROBOT}/odom" in operator.latest, "the bridge", 90)

            placed = with_covariance(pose(CORRIDOR_A, *START))
            await operator.send(op="publish", topic=f"/{ROBOT}/initialpose", msg=placed)
            await operator.until(lambda: f"/{ROBOT}/pose" in operator.latest, "a pose", 60)
            assert operator.entered(CORRIDOR_A)

            goal = pose(CORRIDOR_A, 16, 23.2, 0)
            await operator.send_goal(goal)
            await operator.until(lambda: operator.last_status() == ACTIVE, "the goal taken", 60)
            await operator.until(lambda: any(c[1] > 0.05 for c in commands), "cmd_vel on ROS")
            await operator.cancel_goal()

            await operator.send_goal(goal)
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
        odom_out.unregister()  # latched: later tests' robots would read them
        scan_out.unregister()
        stop_node(bridge)


# --- a ROS 1 robot of rospy nodes, its own move_base, the bridge and the cloud -----------


class RosSide:
    """What the test sees on ROS: ``/map``, ``/initialpose``, ``move_base`` goals, results
    and cancels, ``cmd_vel`` with the node that sent it; and a ``LoadMap`` service."""

    def __init__(self) -> None:
        import rospy  # type: ignore[import-not-found,unused-ignore]
        from actionlib_msgs.msg import GoalID  # type: ignore[import-not-found,unused-ignore]
        from geometry_msgs.msg import (  # type: ignore[import-not-found,unused-ignore]
            PoseWithCovarianceStamped,
            Twist,
        )
        from move_base_msgs.msg import (  # type: ignore[import-not-found,unused-ignore]
            MoveBaseActionGoal,
            MoveBaseActionResult,
        )
        from nav_msgs.msg import OccupancyGrid  # type: ignore[import-not-found,unused-ignore]
        from nav_msgs.srv import LoadMap, LoadMapResponse  # type: ignore[import-not-found,unused-ignore]

        self.maps: list[Any] = []
        self.initial_poses: list[Any] = []
        self.goals: list[tuple[float, Any]] = []
        self.results: list[tuple[float, Any]] = []
        self.cancels: list[float] = []
        self.commands: list[tuple[float, str, float, float]] = []
        self.loaded: list[str] = []
        now = time.monotonic
        rospy.Subscriber("/map", OccupancyGrid, self.maps.append)
        rospy.Subscriber("/initialpose", PoseWithCovarianceStamped, self.initial_poses.append)
        rospy.Subscriber(
            "/move_base/goal", MoveBaseActionGoal, lambda m: self.goals.append((now(), m.goal))
        )
        rospy.Subscriber(
            "/move_base/result", MoveBaseActionResult, lambda m: self.results.append((now(), m))
        )
        rospy.Subscriber("/move_base/cancel", GoalID, lambda _m: self.cancels.append(now()))

        def commanded(msg: Any) -> None:
            sender = msg._connection_header["callerid"]
            self.commands.append((now(), sender, msg.linear.x, msg.angular.z))

        rospy.Subscriber("/cmd_vel", Twist, commanded)

        def load(request: Any) -> Any:
            self.loaded.append(request.map_url)
            return LoadMapResponse(result=0)

        self.service = rospy.Service("/change_map", LoadMap, load)

    def goal_near(self, x: float, y: float, since: float = 0.0) -> bool:
        return any(
            t >= since
            and math.dist((g.target_pose.pose.position.x, g.target_pose.pose.position.y), (x, y))
            < 0.05
            for t, g in self.goals
        )

    def succeeded_since(self, since: float) -> bool:
        return any(t >= since and r.status.status == SUCCEEDED for t, r in self.results)


def echoed_map_info(ros_env: dict[str, str]) -> str:
    """``rostopic echo -n 1 /map/info``, as a person on the robot would look."""
    echoed = subprocess.run(
        ["rostopic", "echo", "-n", "1", "/map/info"],
        env=ros_env,
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert echoed.returncode == 0, echoed.stderr
    return echoed.stdout


@pytest.mark.slow
@pytest.mark.timeout(900)  # its own waits have deadlines; together they outlast 300 s
async def test_a_ros_robot_crosses_sub_maps_through_its_own_move_base(
    node: None,
    ros_env: dict[str, str],
    daphne_server: Any,
    demo_token: str,
    operator_headers: Any,
    tmp_path: Path,
) -> None:
    import websockets

    ros = RosSide()
    processes = [
        start_node(ros_env, tmp_path / "body.log", "robots.agent.sim.ros_robot", "body",
                   "--cloud", daphne_server.url),
        start_node(ros_env, tmp_path / "move_base.log", "robots.agent.sim.ros_robot", "move_base"),
        start_node(ros_env, tmp_path / "bridge.log", "robots.agent.ros", "--server",
                   daphne_server.url, "--token", demo_token, "--load-map", "/change_map",
                   "--map-dir", str(tmp_path / "maps"), "--node", "cloudnav_bridge_robot_0"),
    ]  # fmt: skip

    def logs() -> str:
        goals = [(round(t), g.target_pose.pose.position) for t, g in ros.goals]
        results = [(round(t), r.status.status) for t, r in ros.results]
        return log_tails(tmp_path) + f"\ngoals: {goals}\nresults: {results}"

    try:
        async with websockets.connect(
            daphne_server.rosbridge_url(), additional_headers=operator_headers
        ) as ws:
            operator = Operator(ws)
            await operator.watch("pose", "nav_status", "map_id", "plan")

            # Standing before the entrance tag, the robot reads it: Corridor A on /map.
            await operator.until(lambda: operator.entered(CORRIDOR_A), f"Corridor A\n{logs()}", 120)
            wait_for(lambda: ros.maps, 30, "/map")
            info = echoed_map_info(ros_env)
            assert "width: 392" in info, info
            assert "height: 160" in info, info
            grid = np.asarray(ros.maps[-1].data, dtype=np.int8).reshape(160, 392)
            assert np.array_equal(grid, await cloud_grid(daphne_server, demo_token, CORRIDOR_A))
            placed = wait_for(lambda: ros.initial_poses, 30, "/initialpose")[-1]
            assert placed.pose.covariance[0] > 0  # the tag's covariance, not zeros
            wait_for(lambda: ros.loaded, 30, "load_map")
            assert ros.loaded[-1].endswith("boccioni_1__CorridorA.yaml")

            # The operator's goal in Atrium 1 reaches move_base as a goal to tag 1 first.
            sent = time.monotonic()
            goal = pose(ATRIUM_1, *IN_ATRIUM_1)
            await operator.send_goal(goal)
            await operator.until(
                lambda: ros.goal_near(*TAG_1_APPROACH, since=sent),
                f"a move_base goal\n{logs()}",
                60,
            )
            await operator.until(lambda: operator.last_status() == ACTIVE, "ACTIVE", 30)
            await operator.cancel_goal()
            assert ros.cancels
            assert ros.cancels[-1] >= sent

            # Sent again, it crosses into Atrium 1 by reading tag 1, and arrives.
            await operator.send_goal(goal)
            await operator.until(lambda: f"/{ROBOT}/plan" in operator.latest, "a plan", 60)
            await operator.until(lambda: operator.entered(ATRIUM_1), f"Atrium 1\n{logs()}", 240)
            wait_for(lambda: ros.maps[-1].info.width == 232, 30, "Atrium 1 on /map")
            assert "width: 232" in echoed_map_info(ros_env)
            await operator.until(
                lambda: operator.last_status() == SUCCEEDED, f"SUCCEEDED\n{logs()}", 180
            )
            assert operator.distance_to(IN_ATRIUM_1) < 0.5

            # Back to Corridor A; teleop meanwhile, and the cloud goes away mid-teleop.
            back = pose(CORRIDOR_A, *BACK_IN_CORRIDOR_A)
            await operator.send_goal(back)
            await operator.until(lambda: operator.last_status() == ACTIVE, "ACTIVE again", 30)
            bridge = "/cloudnav_bridge_robot_0"

            def teleop_reached() -> bool:
                turns = (w == pytest.approx(TURNING) for _, s, _, w in ros.commands if s == bridge)
                return any(turns)

            await operator.teleop_until(teleop_reached, TURNING)
            # Teleop has held the goal: the robot sends it again only after its last command
            # (on a slow machine it may have read tag 2 before the teleop began).
            teleop_ended = time.monotonic()
        daphne_server.stop()

        # The dead-man rule on the robot itself: its last teleop command is followed by a
        # stop, though the cloud's own stop can no longer come.
        def stopped_by_the_bridge() -> bool:
            mine = [(t, v, w) for t, s, v, w in ros.commands if s == bridge]
            turning = [t for t, _, w in mine if w == pytest.approx(TURNING)]
            return any(t > turning[-1] and v == w == 0.0 for t, v, w in mine)

        wait_for(stopped_by_the_bridge, 30, "a stop after teleop")
        # Then it drives on with its held maps: tag 2 read, Corridor A on /map again, and
        # move_base takes it to the goal with no cloud at all.
        wait_for(
            lambda: ros.goal_near(*BACK_IN_CORRIDOR_A[:2], since=teleop_ended),
            240,
            f"the goal\n{logs()}",
        )
        assert ros.maps[-1].info.width == 392
        wait_for(lambda: ros.succeeded_since(teleop_ended), 180, f"arrived offline\n{logs()}")
        assert all(p.poll() is None for p in processes), logs()
    finally:
        for process in processes:
            stop_node(process)
