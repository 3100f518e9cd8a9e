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
(``ROS_MASTER_URI``) and Debian's ROS 1 packages (``scripts/setup.sh``). All but the ROS
calls is shared with the ROS 2 bridge (``robots.agent.bridge``).
"""

from __future__ import annotations

import argparse
import asyncio
import logging
from collections.abc import Sequence

from robots.agent.bridge import (
    LOG_FORMAT,
    Bridge,
    bridge_arguments,
    keep_own_logs,
    map_dir_of,
    serve,
)
from robots.agent.ros import ros_path
from robots.domain.params import RobotConfig


def arguments(argv: Sequence[str] | None = None) -> argparse.Namespace:
    summary = (__doc__ or "").split("\n")[0]
    parser = argparse.ArgumentParser(prog="python -m robots.agent.ros", description=summary)
    bridge_arguments(
        parser,
        "move_base",
        action="move_base",
        plan_topic="/move_base/NavfnROS/plan",
        load="a nav_msgs/LoadMap service (change_map)",
    )
    return parser.parse_args(argv)


async def main(options: argparse.Namespace) -> None:
    if not ros_path():
        raise SystemExit("ROS 1 is not installed (scripts/setup.sh installs it)")
    import rospy  # type: ignore[import-not-found,unused-ignore]

    from robots.agent.ros.hardware import RosHardware

    rospy.init_node(options.node, disable_signals=True)
    keep_own_logs(options.log_level)
    hardware = await asyncio.to_thread(
        RosHardware,
        odom=options.odom,
        scan=options.scan,
        camera=options.camera,
        camera_info=options.camera_info,
        cmd_vel=options.cmd_vel,
    )
    try:
        await serve(
            options, Bridge(hardware, stack(options)), RobotConfig(camera_rate=options.camera_rate)
        )
    finally:
        rospy.signal_shutdown("stopped")


def stack(options: argparse.Namespace) -> object:
    """The robot's move_base (None with ``--navigation agent``)."""
    if options.navigation == "agent":
        return None
    from robots.agent.ros.navigation import RosNavigationStack

    return RosNavigationStack(
        action=options.action,
        pose_source=options.pose_source,
        base_frame=options.base_frame,
        plan_topic=options.plan_topic,
        load_map=options.load_map,
        map_dir=map_dir_of(options),
    )


if __name__ == "__main__":
    options = arguments()
    logging.basicConfig(level=options.log_level, format=LOG_FORMAT)
    asyncio.run(main(options))
