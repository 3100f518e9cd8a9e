"""``python -m robots.agent.sim.ros2_robot``: the simulator's robot as a ROS 2 robot with a
Nav2 stand-in, one node per process (``robots.agent.sim.ros2_nodes``), each writing its
events as JSON lines to ``--events``:

    python -m robots.agent.sim.ros2_robot body --cloud http://127.0.0.1:8000 [--start x,y,yaw]
    python -m robots.agent.sim.ros2_robot nav2
    python -m robots.agent.sim.ros2_robot watch

``body`` is the drivers of the demo building's robot, whose tags name ``--cloud``;
``nav2`` the AMCL stand-in, ``NavigateToPose`` server and ``LoadMap`` service; ``watch``
a separate transient-local ``/map`` subscriber. All run on the wall clock, in the
virtualenv ``scripts/ros2_env.sh`` builds.
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from pathlib import Path

from robots.agent.sim.drivers import PERIOD, Pacer, demo_hardware, robot_arguments

WATCHDOG = 1.0
"""Seconds the body obeys a command (the simulator's 0.5 s stopped it between the
commands of a Nav2 stand-in held to 2 Hz on a loaded test machine)."""


def arguments(argv: Sequence[str] | None = None) -> argparse.Namespace:
    parser = robot_arguments("python -m robots.agent.sim.ros2_robot", ("body", "nav2", "watch"))
    parser.add_argument("--events", type=Path, help="JSON lines of what the node does")
    return parser.parse_args(argv)


def main(options: argparse.Namespace) -> None:
    import rclpy  # type: ignore[import-not-found,unused-ignore]
    from rclpy.executors import (  # type: ignore[import-not-found,unused-ignore]
        ExternalShutdownException,
        MultiThreadedExecutor,
    )

    from robots.agent.sim import ros2_nodes

    rclpy.init()
    node = rclpy.create_node(f"sim_{options.node}")
    events = ros2_nodes.Events.to(options.events)
    executor = MultiThreadedExecutor()
    executor.add_node(node)
    if options.node == "body":
        body(node, options, events)
    elif options.node == "nav2":
        from maps.domain.planning import warm_up

        warm_up()
        ros2_nodes.Nav2StandIn(node, events)
    else:
        ros2_nodes.MapWatcher(node, events)
    events.write("ready")
    try:
        executor.spin()
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        rclpy.try_shutdown()


def body(node: object, options: argparse.Namespace, events: object) -> None:
    """The body, stepped every ``PERIOD`` seconds by a timer of ``node``."""
    from robots.agent.sim.ros2_nodes import Ros2Body

    hardware = demo_hardware(options)
    hardware.body.watchdog = WATCHDOG
    robot, pacer = Ros2Body(node, hardware, events), Pacer()  # type: ignore[arg-type]
    node.create_timer(PERIOD, lambda: robot.step(*pacer.tick()))  # type: ignore[attr-defined]


if __name__ == "__main__":
    main(arguments())
