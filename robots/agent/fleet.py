"""Many simulated robots in one process: one asyncio loop, one rosbridge connection and one
HTTP client per robot, one shared simulated world.

The robots share one ``Crowd``: each one's laser, camera and bumpers see the building,
its tags, the other robots and, with ``people`` > 0, that many people walking seeded
routes through the building's corridors, atria and rooms (``--people``,
``--people-seed``).
"""

from __future__ import annotations

import argparse
import asyncio
import logging
import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field, replace

import httpx
import numpy as np

from cloudnav_core.params import RobotConfig
from cloudnav_core.se2 import Pose
from maps.domain.demo_building import demo_building
from maps.domain.planning import warm_up
from robots.agent.client import RosbridgeClient, endpoints
from robots.agent.relocalise import PoseEstimate
from robots.agent.robot import PoseTracker, Robot, declare, particle_filter
from robots.agent.sim.changes import WorldChanges, changed_demo_world
from robots.agent.sim.crowd import Crowd
from robots.agent.sim.hardware import SimHardware
from robots.agent.sim.world import World, demo_world
from robots.agent.supervisor.bundle_cache import BundleCache
from robots.agent.supervisor.maps_supervisor import MapsSupervisor
from robots.agent.visual import VisualMap

logger = logging.getLogger(__name__)


@dataclass(frozen=True)
class FleetOptions:
    """How to build the robots: the server (``http(s)://`` or ``ws(s)://`` base URL),
    where they start, particles of their filters (0: odometry and tags only; None: as
    ``robot`` says), and each robot's config."""

    server: str
    start: Pose | None = None  # every robot's; default: the demo's places by the entrance tag
    starts: tuple[Pose, ...] = ()  # robot by robot (before ``start``)
    particles: int | None = None
    seed: int = 0
    robot: RobotConfig = field(default_factory=RobotConfig)
    changes: WorldChanges | None = None  # how the building differs from its maps
    visual: bool = True  # send keyframes, and ask the cloud where it is when lost
    people: int = 0
    people_seed: int = 0


def add_robot_arguments(parser: argparse.ArgumentParser) -> None:
    """The command-line options of how simulated robots run: ``--time-scale``,
    ``--camera-rate``, ``--camera-timecode``, ``--particles``, ``--planner``, ``--sensors``
    (defaults: ``RobotConfig``'s), ``--people`` and ``--people-seed``."""
    defaults = RobotConfig()
    parser.add_argument("--time-scale", type=float, default=1.0, help="simulated s per wall s")
    parser.add_argument(
        "--camera-rate", type=float, default=defaults.camera_rate, help="JPEG frames/s published"
    )
    parser.add_argument(
        "--camera-timecode", action="store_true",
        help="stamp each camera picture with the wall-clock time code (glass-to-glass delay)",
    )  # fmt: skip
    parser.add_argument(
        "--depth-rate", type=float, default=defaults.depth_rate,
        help="depth images/s published as compressedDepth (and offered as keyframes)",
    )  # fmt: skip
    parser.add_argument(
        "--raw-depth", action="store_true",
        help="also publish each depth image raw on camera/depth/image (800 kB of JSON)",
    )  # fmt: skip
    parser.add_argument(
        "--no-visual", dest="visual", action="store_false",
        help="send no keyframes and never ask the cloud where the robot is",
    )  # fmt: skip
    parser.add_argument(
        "--particles",
        type=int,
        help=f"0: odometry and tags only (default {defaults.localisation.particles})",
    )
    parser.add_argument(
        "--planner",
        choices=("dwa", "teb"),
        default=defaults.local_planner,
        help="local planner: dynamic window or timed elastic band",
    )
    parser.add_argument(
        "--sensors",
        choices=("laser", "rgbd"),
        default=defaults.sensors,
        help="laser, or rgbd: an RGB-D camera and no laser (the scan is made from depth)",
    )
    parser.add_argument("--people", type=int, default=0, help="people walking in the building")
    parser.add_argument("--people-seed", type=int, default=0, help="seed of their routes")


@dataclass
class FleetRobot:
    """One robot of the fleet, with its connections."""

    name: str
    robot: Robot[SimHardware]
    client: RosbridgeClient
    http: httpx.AsyncClient


def build_robot(
    name: str,
    token: str,
    world: World,
    options: FleetOptions,
    index: int = 0,
    crowd: Crowd | None = None,
) -> FleetRobot:
    """A robot named ``name`` with its rosbridge and HTTP clients (not started)."""
    http_base, ws_url = endpoints(options.server)
    http = httpx.AsyncClient(
        base_url=http_base, headers={"Authorization": f"Token {token}"}, timeout=10.0
    )
    seed, config = options.seed + 10 * index, options.robot
    start = options.starts[index] if index < len(options.starts) else options.start
    start = start or demo_start(index)
    hardware = SimHardware(
        world, start, seed=seed, limits=config.body, crowd=crowd, sensors=config.sensors
    )
    particles = config.localisation.particles if options.particles is None else options.particles
    filter_params = config.localisation  # its scan comes from where the hardware takes it
    filter_params = replace(
        filter_params, beams=replace(filter_params.beams, laser_pose=hardware.scan_mount)
    )
    tracker = PoseTracker(particle_filter(particles, seed, filter_params))
    supervisor = MapsSupervisor(BundleCache(http), tracker)
    client = RosbridgeClient(ws_url, token, seed=seed)
    visual = VisualMap(http, hardware.camera.model) if options.visual else None
    robot = Robot(hardware, supervisor, tracker, client, options.robot, visual=visual)
    declare(robot, client)
    return FleetRobot(name, robot, client, http)


def demo_start(index: int) -> Pose:
    """Where the demo's robot number ``index`` begins: within reading range of the entrance
    tag (``ROBOT_STARTS``), so it localises at once."""
    starts = demo_building().robot_starts
    return starts[index % len(starts)]


def build_fleet(tokens: Iterable[tuple[str, str]], options: FleetOptions) -> list[FleetRobot]:
    """Robots for ``(name, token)`` pairs in the demo building (as ``options.changes``
    left it), its tags naming the server as their cloud, with ``options.people`` people
    walking in it."""
    cloud = endpoints(options.server)[0]
    world = (
        demo_world(cloud) if options.changes is None else changed_demo_world(options.changes, cloud)
    )
    crowd = demo_crowd(world, options.people, options.people_seed)
    return [
        build_robot(name, token, world, options, index, crowd)
        for index, (name, token) in enumerate(tokens)
    ]


def demo_crowd(world: World, people: int, seed: int) -> Crowd:
    """``people`` people on seeded routes inside the demo building (never in the street)."""
    inside = np.asarray(demo_building().world) == 0  # free and mapped: not the street
    return Crowd.seeded(world, people, seed, inside) if people else Crowd(world)


async def run_fleet(fleet: list[FleetRobot], time_scale: float = 1.0) -> None:
    """Connect and run every robot until cancelled; then close their connections."""
    warm_up()  # compile (or load) the planner before the first tick needs it
    tasks = [asyncio.create_task(member.client.run()) for member in fleet]
    tasks += [asyncio.create_task(member.robot.run(time_scale)) for member in fleet]
    logger.info("%d robot(s) running at %g x real time", len(fleet), time_scale)
    try:
        await asyncio.gather(*tasks)
    finally:
        for task in tasks:
            task.cancel()
        await asyncio.gather(*tasks, return_exceptions=True)
        await asyncio.gather(*(_close(member) for member in fleet))


async def place_at_truth(fleet: list[FleetRobot], map_ids: Sequence[str]) -> None:
    """Tell each robot where it truly stands in its sub-map of ``map_ids`` (robot by
    robot), as an operator's initial pose does (a robot without a camera reads no tag).
    Raises BundleError when a map cannot be had."""
    for member, map_id in zip(fleet, map_ids, strict=True):
        estimate = PoseEstimate(*member.robot.hardware.true_pose, np.diag([1e-4, 1e-4, 1e-4]))
        await member.robot.supervisor.relocate(estimate, map_id, member.robot.tracker.odom)


async def _close(member: FleetRobot) -> None:
    await member.client.close()
    await member.http.aclose()


def parse_pose(text: str) -> Pose:
    """``"x,y,yaw"`` (metres, radians). Raises ValueError."""
    try:
        values = [float(part) for part in text.split(",")]
    except ValueError:
        values = []
    if len(values) != 3 or not all(math.isfinite(v) for v in values):
        raise ValueError(f"'{text}' is not x,y,yaw")
    return values[0], values[1], values[2]
