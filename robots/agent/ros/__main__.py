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
from collections.abc import Sequence
from typing import Any

from robots.agent.bridge import (
    bridge_parser,
    driver_topics,
    run_bridge,
    run_node,
    stack_options,
)
from robots.agent.ros import ros_path


def arguments(argv: Sequence[str] | None = None) -> argparse.Namespace:
    parser = bridge_parser(
        "python -m robots.agent.ros",
        __doc__,
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

    rospy.init_node(options.node, disable_signals=True)
    try:
        await run_bridge(options, lambda: hardware(options), lambda: stack(options))
    finally:
        rospy.signal_shutdown("stopped")


def hardware(options: argparse.Namespace) -> Any:
    from robots.agent.ros.hardware import RosHardware

    return RosHardware(**driver_topics(options))


def stack(options: argparse.Namespace) -> Any:
    """The robot's move_base."""
    from robots.agent.ros.navigation import RosNavigationStack

    return RosNavigationStack(**stack_options(options))


if __name__ == "__main__":
    options = arguments()
    run_node(options, main(options))
