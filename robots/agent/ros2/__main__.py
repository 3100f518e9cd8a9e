"""``python -m robots.agent.ros2``: a ROS 2 robot with Nav2 on CloudNav, one node.

    python -m robots.agent.ros2 --server https://cloudnav.example --token cnr_... \\
        [--odom odom --scan scan --cmd-vel cmd_vel [--cmd-vel-stamped]] \\
        [--camera camera/image/compressed --camera-type compressed|raw] \\
        [--camera-info camera/camera_info] [--navigation nav2|agent] \\
        [--nav2-action navigate_to_pose --pose-source amcl_pose|tf --plan-topic /plan] \\
        [--load-map /map_server/load_map --map-dir DIR] [--ros-args -r odom:=/wheel/odom]

Runs the robot's software (tag detector, Maps Supervisor, relocalisation on tags) on the
robot's ROS 2 topics (``Ros2Hardware``) and relays to the cloud over rosbridge with the
robot's token, under the fleet's topic names and rates. With ``--navigation nav2`` (the
default) Nav2 drives (``Nav2Stack``): each sub-map entered goes on ``/map`` with
transient-local QoS (and to Nav2's map server with ``--load-map``), each pose reset on
``/initialpose``, each leg as a ``NavigateToPose`` goal; with ``--navigation agent`` the
agent's own planner and controller drive on ``cmd_vel``. Arguments after ``--ros-args``
go to rclpy (remappings, ``-p use_sim_time:=true``). All but the ROS calls is shared with
the ROS 1 bridge (``robots.agent.bridge``).
"""

from __future__ import annotations

import argparse
import logging
import os
import signal
import threading
from collections.abc import Sequence
from typing import Any

from robots.agent.bridge import (
    bridge_parser,
    driver_topics,
    run_bridge,
    run_node,
    stack_options,
)

logger = logging.getLogger(__name__)


def arguments(argv: Sequence[str] | None = None) -> tuple[argparse.Namespace, list[str]]:
    """The bridge's options, and the arguments for rclpy (``--ros-args ...``)."""
    parser = bridge_parser(
        "python -m robots.agent.ros2",
        __doc__,
        "nav2",
        action="navigate_to_pose",
        plan_topic="/plan",
        load="Nav2's map server's nav2_msgs/LoadMap service (/map_server/load_map)",
    )
    parser.add_argument("--camera-type", choices=("compressed", "raw"), default="compressed")
    parser.add_argument("--cmd-vel-stamped", action="store_true", help="TwistStamped")
    return parser.parse_known_args(argv)


async def main(options: argparse.Namespace, ros_args: list[str]) -> None:
    import rclpy  # type: ignore[import-not-found,unused-ignore]
    from rclpy.executors import MultiThreadedExecutor  # type: ignore[import-not-found,unused-ignore]

    rclpy.init(args=["robots.agent.ros2", *ros_args])
    node = rclpy.create_node(options.node)
    executor = MultiThreadedExecutor()
    executor.add_node(node)
    ending = threading.Event()
    spinning = threading.Thread(target=spin_or_stop, args=(executor, ending), daemon=True)
    spinning.start()
    try:
        await run_bridge(options, lambda: hardware(node, options), lambda: stack(node, options))
    finally:
        ending.set()
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown()


def spin_or_stop(executor: Any, ending: threading.Event) -> None:
    """Spin ``executor``; if spinning fails before the bridge is ``ending``, the bridge
    stops (SIGTERM to itself: the robot is stopped and its goal cancelled on the way out)
    rather than drive on readings that no longer come."""
    try:
        executor.spin()
    except Exception:
        if ending.is_set():
            return
        logger.exception("the ROS 2 executor failed: the bridge stops")
        os.kill(os.getpid(), signal.SIGTERM)


def hardware(node: Any, options: argparse.Namespace) -> Any:
    from robots.agent.ros2.hardware import Ros2Hardware

    return Ros2Hardware(
        node,
        **driver_topics(options),
        camera_type=options.camera_type,
        stamped=options.cmd_vel_stamped,
    )


def stack(node: Any, options: argparse.Namespace) -> Any:
    """The robot's Nav2."""
    from robots.agent.ros2.navigation import Nav2Stack

    return Nav2Stack(node, **stack_options(options))


if __name__ == "__main__":
    parsed, rest = arguments()
    run_node(parsed, main(parsed, rest))
