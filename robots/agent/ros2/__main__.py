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
import asyncio
import logging
import threading
from collections.abc import Sequence
from typing import Any

from robots.agent.bridge import (
    LOG_FORMAT,
    Bridge,
    bridge_arguments,
    keep_own_logs,
    map_dir_of,
    serve,
)
from robots.domain.params import RobotConfig


def arguments(argv: Sequence[str] | None = None) -> tuple[argparse.Namespace, list[str]]:
    """The bridge's options, and the arguments for rclpy (``--ros-args ...``)."""
    summary = (__doc__ or "").split("\n")[0]
    parser = argparse.ArgumentParser(prog="python -m robots.agent.ros2", description=summary)
    bridge_arguments(
        parser,
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
    keep_own_logs(options.log_level)
    executor = MultiThreadedExecutor()
    executor.add_node(node)
    spinning = threading.Thread(target=executor.spin, daemon=True)
    spinning.start()
    try:
        hardware = await asyncio.to_thread(hardware_of, node, options)
        config = RobotConfig(camera_rate=options.camera_rate)
        await serve(options, Bridge(hardware, stack(node, options)), config)
    finally:
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown()


def hardware_of(node: Any, options: argparse.Namespace) -> Any:
    from robots.agent.ros2.hardware import Ros2Hardware

    return Ros2Hardware(
        node,
        odom=options.odom,
        scan=options.scan,
        camera=options.camera,
        camera_type=options.camera_type,
        camera_info=options.camera_info,
        cmd_vel=options.cmd_vel,
        stamped=options.cmd_vel_stamped,
    )


def stack(node: Any, options: argparse.Namespace) -> Any:
    """The robot's Nav2 (None with ``--navigation agent``)."""
    if options.navigation == "agent":
        return None
    from robots.agent.ros2.navigation import Nav2Stack

    return Nav2Stack(
        node,
        action=options.action,
        pose_source=options.pose_source,
        base_frame=options.base_frame,
        plan_topic=options.plan_topic,
        load_map=options.load_map,
        map_dir=map_dir_of(options),
    )


if __name__ == "__main__":
    parsed, rest = arguments()
    logging.basicConfig(level=parsed.log_level, format=LOG_FORMAT)
    asyncio.run(main(parsed, rest))
