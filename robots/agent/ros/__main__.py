"""``python -m robots.agent.ros``: a ROS 1 robot on CloudNav, one node.

    python -m robots.agent.ros --server https://cloudnav.example --token cnr_... \\
        [--odom odom --scan scan --camera camera/image/compressed --cmd-vel cmd_vel]

Runs the robot's software (tag detector, Maps Supervisor, pose tracking, navigation) on the
robot's ROS topics (``RosHardware``) and relays to the cloud over rosbridge with the
robot's token, under the fleet's topic names and rates. Topic names are resolved in the
node's namespace, so ROS remappings (``odom:=/wheel/odom``) apply. Needs a roscore
(``ROS_MASTER_URI``) and Debian's ROS 1 packages (``scripts/setup.sh``).
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import logging
import signal
from collections.abc import Sequence

import httpx

from maps.domain.planning import warm_up
from robots.agent.client import RosbridgeClient, endpoints
from robots.agent.robot import PoseTracker, Robot, declare, particle_filter
from robots.agent.ros import ros_path
from robots.agent.supervisor import BundleCache, MapsSupervisor
from robots.domain.params import RobotConfig


def arguments(argv: Sequence[str] | None = None) -> argparse.Namespace:
    summary = (__doc__ or "").split("\n")[0]
    parser = argparse.ArgumentParser(prog="python -m robots.agent.ros", description=summary)
    parser.add_argument("--server", required=True, help="the server, http://host:port or ws://...")
    parser.add_argument("--token", required=True, help="the robot's token")
    parser.add_argument("--node", default="cloudnav_bridge", help="the ROS node's name")
    parser.add_argument("--odom", default="odom")
    parser.add_argument("--scan", default="scan")
    parser.add_argument("--camera", default="camera/image/compressed")
    parser.add_argument("--cmd-vel", default="cmd_vel")
    parser.add_argument("--camera-rate", type=float, default=RobotConfig().camera_rate)
    parser.add_argument("--particles", type=int, help="0: odometry and tags only")
    parser.add_argument("--log-level", default="INFO")
    return parser.parse_args(argv)


async def main(options: argparse.Namespace) -> None:
    if not ros_path():
        raise SystemExit("ROS 1 is not installed (scripts/setup.sh installs it)")
    import rospy  # type: ignore[import-not-found,unused-ignore]

    from robots.agent.ros.hardware import RosHardware

    rospy.init_node(options.node, disable_signals=True)
    config = RobotConfig(camera_rate=options.camera_rate)
    hardware = await asyncio.to_thread(
        RosHardware,
        odom=options.odom,
        scan=options.scan,
        camera=options.camera,
        cmd_vel=options.cmd_vel,
    )
    http_base, ws_url = endpoints(options.server)
    http = httpx.AsyncClient(
        base_url=http_base, headers={"Authorization": f"Token {options.token}"}, timeout=10.0
    )
    particles = config.localisation.particles if options.particles is None else options.particles
    tracker = PoseTracker(particle_filter(particles, None, config.localisation))
    supervisor = MapsSupervisor(BundleCache(http), tracker)
    client = RosbridgeClient(ws_url, options.token)
    robot = Robot(hardware, supervisor, tracker, client, config)
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
        hardware.command(0.0, 0.0)
        await client.close()
        await http.aclose()
        rospy.signal_shutdown("stopped")


if __name__ == "__main__":
    options = arguments()
    logging.basicConfig(level=options.log_level, format="%(asctime)s %(name)s %(message)s")
    asyncio.run(main(options))
