"""``python -m robots.agent.ros``: a ROS 1 robot on CloudNav, one node.

    python -m robots.agent.ros --server https://cloudnav.example --token cnr_... \\
        [--odom odom --scan scan --camera camera/image/compressed --cmd-vel cmd_vel] \\
        [--camera-info camera/camera_info] \\
        [--navigation move_base --pose-source amcl_pose|tf --load-map change_map]

Runs the robot's software (tag detector, Maps Supervisor, relocalisation on tags) on the
robot's ROS topics (``RosHardware``) and relays to the cloud over rosbridge with the
robot's token, under the fleet's topic names and rates. With ``--navigation move_base``
(the default) the robot's own navigation stack drives (``RosNavigationStack``): each
sub-map entered goes on the latched ``/map`` (and to a map server's ``LoadMap`` service
with ``--load-map``), each pose reset on ``/initialpose``, each leg as a ``move_base``
goal, and the pose comes from AMCL or tf; with ``--navigation agent`` the agent's own
planner and controller drive on ``cmd_vel``. Topic names are resolved in the node's
namespace, so ROS remappings (``odom:=/wheel/odom``) apply. Needs a roscore
(``ROS_MASTER_URI``) and Debian's ROS 1 packages (``scripts/setup.sh``).
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import logging
import signal
import tempfile
from collections.abc import Sequence
from pathlib import Path

import httpx

from maps.domain.planning import warm_up
from robots.agent.client import RosbridgeClient, endpoints
from robots.agent.navigation import LegDriver
from robots.agent.robot import PoseTracker, Robot, declare, particle_filter
from robots.agent.ros import ros_path
from robots.agent.stack import StackDriver, StackPoseTracker
from robots.agent.supervisor import BundleCache, MapsSupervisor
from robots.domain.params import RobotConfig

LOG_FORMAT = "%(asctime)s %(name)s %(message)s"
PROJECT_PACKAGES = frozenset({"robots", "maps", "telemetry", "httpx"})


def arguments(argv: Sequence[str] | None = None) -> argparse.Namespace:
    summary = (__doc__ or "").split("\n")[0]
    parser = argparse.ArgumentParser(prog="python -m robots.agent.ros", description=summary)
    parser.add_argument("--server", required=True, help="the server, http://host:port or ws://...")
    parser.add_argument("--token", required=True, help="the robot's token")
    parser.add_argument("--node", default="cloudnav_bridge", help="the ROS node's name")
    parser.add_argument("--odom", default="odom")
    parser.add_argument("--scan", default="scan")
    parser.add_argument("--camera", default="camera/image/compressed")
    parser.add_argument("--camera-info", default="camera/camera_info", help="its calibration")
    parser.add_argument("--cmd-vel", default="cmd_vel")
    parser.add_argument("--camera-rate", type=float, default=RobotConfig().camera_rate)
    parser.add_argument("--particles", type=int, help="0: odometry and tags only (agent)")
    parser.add_argument("--navigation", choices=("move_base", "agent"), default="move_base")
    parser.add_argument("--move-base", default="move_base", help="the action's name")
    parser.add_argument("--pose-source", default="amcl_pose", help="a pose topic, or tf")
    parser.add_argument("--base-frame", default="base_footprint", help="with tf")
    parser.add_argument("--plan-topic", default="/move_base/NavfnROS/plan")
    parser.add_argument("--load-map", help="a nav_msgs/LoadMap service (change_map)")
    parser.add_argument("--map-dir", type=Path, help="where --load-map's files go")
    parser.add_argument("--log-level", default="INFO")
    return parser.parse_args(argv)


async def main(options: argparse.Namespace) -> None:
    if not ros_path():
        raise SystemExit("ROS 1 is not installed (scripts/setup.sh installs it)")
    import rospy  # type: ignore[import-not-found,unused-ignore]

    from robots.agent.ros.hardware import RosHardware

    rospy.init_node(options.node, disable_signals=True)
    keep_own_logs(options.log_level)
    config = RobotConfig(camera_rate=options.camera_rate)
    hardware = await asyncio.to_thread(
        RosHardware,
        odom=options.odom,
        scan=options.scan,
        camera=options.camera,
        camera_info=options.camera_info,
        cmd_vel=options.cmd_vel,
    )
    http_base, ws_url = endpoints(options.server)
    http = httpx.AsyncClient(
        base_url=http_base, headers={"Authorization": f"Token {options.token}"}, timeout=10.0
    )
    tracker, driver = navigation(options, config)
    supervisor = MapsSupervisor(BundleCache(http), tracker)
    client = RosbridgeClient(ws_url, options.token)
    robot = Robot(hardware, supervisor, tracker, client, config, driver=driver)
    declare(robot, client)
    warm_up()
    tasks = [asyncio.create_task(client.run()), asyncio.create_task(robot.run(1.0))]
    loop = asyncio.get_running_loop()
    for stop in (signal.SIGINT, signal.SIGTERM):
        loop.add_signal_handler(stop, lambda: [task.cancel() for task in tasks])
    try:
        with contextlib.suppress(asyncio.CancelledError):
            await asyncio.gather(*tasks)
    finally:
        robot.navigator.driver.clear()  # a move_base goal of the bridge's ends with it
        hardware.command(0.0, 0.0)
        await client.close()
        await http.aclose()
        rospy.signal_shutdown("stopped")


def keep_own_logs(level: str) -> None:
    """Undo what ``rospy.init_node`` does to logging (its configuration replaces the
    root's handlers and disables the loggers that existed before it): the robot's
    software logs to stderr at ``level`` as it did."""
    logging.basicConfig(level=level, format=LOG_FORMAT, force=True)
    for name, found in logging.root.manager.loggerDict.items():
        if name.split(".")[0] in PROJECT_PACKAGES and isinstance(found, logging.Logger):
            found.disabled = False


def navigation(
    options: argparse.Namespace, config: RobotConfig
) -> tuple[PoseTracker, LegDriver | None]:
    """The pose tracker and leg driver: through move_base, or the agent's own."""
    if options.navigation == "agent":
        particles = options.particles
        particles = config.localisation.particles if particles is None else particles
        return PoseTracker(particle_filter(particles, None, config.localisation)), None
    from robots.agent.ros.navigation import RosNavigationStack

    map_dir = options.map_dir or Path(tempfile.mkdtemp(prefix="cloudnav-maps-"))
    stack = RosNavigationStack(
        action=options.move_base,
        pose_source=options.pose_source,
        base_frame=options.base_frame,
        plan_topic=options.plan_topic,
        load_map=options.load_map,
        map_dir=map_dir,
    )
    return StackPoseTracker(stack), StackDriver(stack, config)


if __name__ == "__main__":
    options = arguments()
    logging.basicConfig(level=options.log_level, format=LOG_FORMAT)
    asyncio.run(main(options))
