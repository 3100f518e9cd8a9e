"""``python -m robots.agent.sim.ros_robot``: the simulator's robot as a ROS 1 robot, one
node per process (``robots.agent.sim.ros_nodes``):

    python -m robots.agent.sim.ros_robot body --cloud http://127.0.0.1:8000 [--start x,y,yaw]
    python -m robots.agent.sim.ros_robot move_base

``body`` is the drivers (``cmd_vel`` in; ``odom``, tf, ``scan``, the camera out) of the
demo building's robot, whose tags name ``--cloud``; ``move_base`` is a minimal navigation
stack (localiser publishing ``amcl_pose``, the ``move_base`` action on ``/map``). Both run
on the wall clock. Needs a roscore (``ROS_MASTER_URI``) and Debian's ROS 1 packages
(``scripts/setup.sh``).
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Sequence

from robots.agent.fleet import demo_start, parse_pose
from robots.agent.ros import ros_path

PERIOD = 0.1
"""Seconds between the body's steps, odometry and scans (10 Hz)."""
LONGEST_STEP = 0.5
"""Seconds: a step the machine held up longer is cut to this (the body never jumps)."""


def arguments(argv: Sequence[str] | None = None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(prog="python -m robots.agent.sim.ros_robot")
    parser.add_argument("node", choices=("body", "move_base"))
    parser.add_argument("--cloud", default="http://127.0.0.1:8000", help="named by the tags")
    parser.add_argument("--start", type=parse_pose, default=demo_start(0), help="x,y,yaw")
    parser.add_argument("--seed", type=int, default=0)
    return parser.parse_args(argv)


def run_body(options: argparse.Namespace) -> None:
    import rospy  # type: ignore[import-not-found,unused-ignore]

    from robots.agent.sim.hardware import SimHardware
    from robots.agent.sim.ros_nodes import RosBody
    from robots.agent.sim.world import demo_world

    rospy.init_node("sim_robot")
    hardware = SimHardware(demo_world(options.cloud), options.start, seed=options.seed)
    body, ticks, last = RosBody(hardware), 0, time.monotonic()
    rate = rospy.Rate(1 / PERIOD)
    while not rospy.is_shutdown():
        now, ticks = time.monotonic(), ticks + 1
        body.step(min(now - last, LONGEST_STEP), ticks)
        last = now
        try:
            rate.sleep()
        except rospy.ROSInterruptException:
            break


def run_move_base() -> None:
    import rospy  # type: ignore[import-not-found,unused-ignore]

    from maps.domain.planning import warm_up
    from robots.agent.sim.ros_nodes import MoveBaseStandIn

    warm_up()
    rospy.init_node("move_base")
    MoveBaseStandIn()
    rospy.spin()


def main(options: argparse.Namespace) -> None:
    if not ros_path():
        raise SystemExit("ROS 1 is not installed (scripts/setup.sh installs it)")
    if options.node == "body":
        run_body(options)
    else:
        run_move_base()


if __name__ == "__main__":
    main(arguments())
