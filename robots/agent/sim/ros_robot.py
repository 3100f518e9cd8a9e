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
from collections.abc import Sequence

from robots.agent.ros import ros_path
from robots.agent.sim.drivers import PERIOD, Pacer, demo_hardware, robot_arguments


def arguments(argv: Sequence[str] | None = None) -> argparse.Namespace:
    parser = robot_arguments("python -m robots.agent.sim.ros_robot", ("body", "move_base"))
    return parser.parse_args(argv)


def run_body(options: argparse.Namespace) -> None:
    import rospy  # type: ignore[import-not-found,unused-ignore]

    from robots.agent.sim.ros_nodes import RosBody

    rospy.init_node("sim_robot")
    body, pacer = RosBody(demo_hardware(options)), Pacer()
    rate = rospy.Rate(1 / PERIOD)
    while not rospy.is_shutdown():
        body.step(*pacer.tick())
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
