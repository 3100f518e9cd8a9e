"""What a ROS bridge does that is no ROS call, shared by the ROS 1 backend
(``robots.agent.ros``) and the ROS 2 one (``robots.agent.ros2``): they differ only in how
they subscribe, publish and call.

- ``DriverReadings``: the robot's drivers' latest odometry, scan and camera frame as the
  hardware seam (``robots.agent.hardware.Hardware``) reads them; the backends feed it from
  their callbacks and publish ``cmd_vel``.
- ``StackReadings``: the book a navigation stack backend keeps (the sub-map on ``/map``,
  the pose source's latest pose, the planner's plan, the goal's progress).
- ``write_map_files``: a sub-map as map-server files, for a ``LoadMap`` service.
- ``bridge_parser``, ``run_bridge`` and ``serve``: the command line, the startup and the
  run loop of the node: the robot's software (tag detector, Maps Supervisor,
  relocalisation) relaying to the cloud.

ROS messages are read by attribute (``msg.pose.pose.position.x``), which ROS 1 and ROS 2
messages share; only their array fields differ in case (``K`` and ``k``), which callers
pass in.
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import logging
import math
import signal
import tempfile
import threading
import time
from collections.abc import Callable, Coroutine, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, TypedDict

import cv2
import httpx
import numpy as np
from numpy.typing import NDArray

from cloudnav_core.camera import CameraModel
from cloudnav_core.grid import FREE_THRESH, OCCUPIED_THRESH
from cloudnav_core.messages import Json, Odometry, ScanGeometry, laser_scan, odometry
from cloudnav_core.params import RobotConfig
from cloudnav_core.se2 import Point, Pose
from maps.domain.mapfile import MapMetadata, export_map, map_yaml_text
from maps.domain.planning import warm_up
from robots.agent.client import RosbridgeClient, endpoints
from robots.agent.navigation.legs import LegDriver
from robots.agent.robot import PoseTracker, Robot, declare, particle_filter
from robots.agent.stack import StackDriver, StackPoseTracker
from robots.agent.supervisor.bundle_cache import BundleCache
from robots.agent.supervisor.maps_supervisor import MapsSupervisor

logger = logging.getLogger(__name__)

LOG_FORMAT = "%(asctime)s %(name)s %(message)s"
PROJECT_PACKAGES = frozenset({"robots", "maps", "telemetry", "httpx"})
STALE_FRAME = 1.0
"""Seconds after which the latest camera frame no longer counts as a view of now."""
PLANAR = (0, 1, 5)
"""x, y and yaw among ROS's covariance axes (x, y, z, roll, pitch, yaw)."""


# --- conversions -----------------------------------------------------------------------


def yaw_of(orientation: Any) -> float:
    q = orientation
    return math.atan2(2 * (q.w * q.z + q.x * q.y), 1 - 2 * (q.y * q.y + q.z * q.z))


def quaternion_of(yaw: float) -> tuple[float, float, float, float]:
    """(x, y, z, w) of a rotation by ``yaw`` about z."""
    return (0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2))


def pose_of(msg: Any) -> Pose:
    """The SE(2) pose of a ``geometry_msgs/Pose``."""
    return (msg.position.x, msg.position.y, yaw_of(msg.orientation))


def set_pose(msg: Any, pose: Pose) -> None:
    """Write an SE(2) pose into a ``geometry_msgs/Pose``."""
    msg.position.x, msg.position.y = float(pose[0]), float(pose[1])
    o = msg.orientation
    o.x, o.y, o.z, o.w = quaternion_of(pose[2])


def pose_of_transform(transform: Any) -> Pose:
    """The SE(2) pose of a ``geometry_msgs/Transform``."""
    t = transform
    return (t.translation.x, t.translation.y, yaw_of(t.rotation))


def plan_of(msg: Any) -> list[Point]:
    """The points of a ``nav_msgs/Path``."""
    return [(p.pose.position.x, p.pose.position.y) for p in msg.poses]


def write_grid_info(msg: Any, cells: NDArray[np.int8], resolution: float, origin: Pose) -> None:
    """A ``nav_msgs/OccupancyGrid``'s ``info`` of ``cells`` (but ``map_load_time``); its
    data each version writes its own way."""
    msg.info.resolution = float(resolution)
    msg.info.height, msg.info.width = (int(n) for n in cells.shape)
    set_pose(msg.info.origin, origin)


def write_initial_pose(msg: Any, pose: Pose, covariance: NDArray[np.float64]) -> None:
    """A ``geometry_msgs/PoseWithCovarianceStamped``'s pose and covariance (x, y, yaw)."""
    set_pose(msg.pose.pose, pose)
    msg.pose.covariance = full_covariance(covariance)


def full_covariance(planar: NDArray[np.float64]) -> list[float]:
    """ROS's 6x6 covariance (row-major, 36 values) of a 3x3 one of (x, y, yaw)."""
    full = np.zeros((6, 6))
    full[np.ix_(PLANAR, PLANAR)] = np.asarray(planar, dtype=np.float64).reshape(3, 3)
    return [float(value) for value in full.ravel()]


def planar_covariance(values: Sequence[float]) -> NDArray[np.float64]:
    """The (x, y, yaw) 3x3 of ROS's 6x6 covariance."""
    full = np.asarray(values, dtype=np.float64).reshape(6, 6)
    return full[np.ix_(PLANAR, PLANAR)]


def scan_geometry(msg: Any) -> ScanGeometry:
    """The beams and range of a ``sensor_msgs/LaserScan``."""
    return {
        "angle_min": msg.angle_min,
        "angle_max": msg.angle_max,
        "angle_increment": msg.angle_increment,
        "time_increment": msg.time_increment,
        "scan_time": msg.scan_time,
        "range_min": msg.range_min,
        "range_max": msg.range_max,
    }


def camera_model_of(
    k: Sequence[float], width: int, height: int, mounting: CameraModel | None = None
) -> CameraModel:
    """``mounting`` (the default camera) with the size and K matrix of a
    ``sensor_msgs/CameraInfo``; as it is if K is uncalibrated (all zero)."""
    mounting = mounting or CameraModel()
    k = [float(value) for value in k]
    if k[0] <= 0 or k[4] <= 0:
        return mounting
    return replace(
        mounting, width=int(width), height=int(height), fx=k[0], fy=k[4], cx=k[2], cy=k[5]
    )


RAW_ENCODINGS = {"mono8": 1, "8UC1": 1, "bgr8": 3, "rgb8": 3, "8UC3": 3}
"""``sensor_msgs/Image`` encodings the tag detector reads, with their channels."""


def image_of_raw(encoding: str, height: int, width: int, data: bytes) -> NDArray[np.uint8]:
    """A grey or BGR array of a raw ``sensor_msgs/Image``. Raises ValueError for an
    encoding other than ``RAW_ENCODINGS`` or data of the wrong size."""
    channels = RAW_ENCODINGS.get(encoding)
    if channels is None:
        raise ValueError(f"unsupported image encoding {encoding!r}")
    flat = np.frombuffer(bytes(data), dtype=np.uint8)
    if flat.size != height * width * channels:
        raise ValueError(f"{flat.size} bytes for a {width}x{height} {encoding} image")
    image = flat.reshape((height, width, channels) if channels > 1 else (height, width))
    return np.ascontiguousarray(image[..., ::-1] if encoding == "rgb8" else image)


def image_of_jpeg(data: bytes) -> NDArray[np.uint8] | None:
    """The decoded frame of a ``sensor_msgs/CompressedImage``; None if it does not decode."""
    image = cv2.imdecode(np.frombuffer(bytes(data), dtype=np.uint8), cv2.IMREAD_UNCHANGED)
    return None if image is None else np.asarray(image, dtype=np.uint8)


# --- the drivers as the hardware seam --------------------------------------------------


class BatteryReading:
    """The latest ``sensor_msgs/BatteryState`` of the robot's battery topic. Until the
    first arrives it reads full at 0 V (a robot without one never says otherwise)."""

    def __init__(self) -> None:
        self.charge = 1.0
        self.voltage = 0.0

    def on_state(self, msg: Any) -> None:
        if math.isfinite(msg.percentage):
            self.charge = min(1.0, max(0.0, float(msg.percentage)))
        if math.isfinite(msg.voltage):
            self.voltage = float(msg.voltage)


class DriverReadings:
    """The latest odometry, scan and camera frame of a ROS robot (a ``Hardware`` but for
    ``command``, which each backend publishes). A backend calls ``on_odom``, ``on_scan``
    and ``on_image`` from its callbacks, and ``ready`` with the first odometry and scan
    (or ``wait_ready``, which takes them from those callbacks)."""

    def __init__(self, camera_model: CameraModel) -> None:
        self.camera_model = camera_model
        self.battery = BatteryReading()
        self._lock = threading.Lock()
        self._odom: Any = None
        self._scan: Any = None
        self._image: NDArray[np.uint8] | None = None
        self._image_at = -math.inf
        self.scan_angles: NDArray[np.float64] = np.zeros(0)
        self.scan_mount: Pose = (0.0, 0.0, 0.0)  # the laser's frame taken as the base's
        self._both_came = threading.Event()

    def ready(self, odom: Any, scan: Any) -> None:
        """Take the first odometry and scan (the scan's beams fix ``scan_angles``)."""
        self._odom, self._scan = odom, scan
        self.scan_angles = scan.angle_min + scan.angle_increment * np.arange(len(scan.ranges))

    def wait_ready(self, timeout: float) -> bool:
        """Wait up to ``timeout`` seconds for ``on_odom`` and ``on_scan`` to have had a
        message each, then take the latest as the first (``ready``); False if one never came."""
        if not self._both_came.wait(timeout):
            return False
        with self._lock:
            odom, scan = self._odom, self._scan
        self.ready(odom, scan)
        return True

    def on_odom(self, msg: Any) -> None:
        with self._lock:
            self._odom = msg
            self._note_arrival()

    def on_scan(self, msg: Any) -> None:
        with self._lock:
            self._scan = msg
            self._note_arrival()

    def _note_arrival(self) -> None:
        if self._odom is not None and self._scan is not None:
            self._both_came.set()

    def on_image(self, image: NDArray[np.uint8] | None) -> None:
        """A decoded frame (None: one that did not decode, dropped)."""
        if image is not None:
            with self._lock:
                self._image, self._image_at = image, time.monotonic()

    @property
    def odom_pose(self) -> Pose:
        with self._lock:
            pose = self._odom.pose.pose
        return pose_of(pose)

    @property
    def reported_velocity(self) -> tuple[float, float]:
        with self._lock:
            twist = self._odom.twist.twist
        return (twist.linear.x, twist.angular.z)

    def advance(self, seconds: float) -> None:
        """Nothing to do: the robot's clock is the wall clock, which ``Robot.run`` paces
        (and the drivers' callbacks keep the latest data fresh meanwhile)."""

    def scan(self) -> NDArray[np.float32]:
        with self._lock:
            ranges = self._scan.ranges
        return np.asarray(ranges, dtype=np.float32)

    def scan_message(self, ranges: NDArray[np.float32], seconds: float) -> Json:
        with self._lock:
            spec = self._scan
        return dict(
            laser_scan(spec.header.frame_id, ranges.tolist(), seconds, **scan_geometry(spec))
        )

    def odometry_message(self, seconds: float) -> Odometry:
        with self._lock:
            msg = self._odom
        return odometry(
            msg.header.frame_id or "odom",
            msg.child_frame_id or "base_footprint",
            seconds,
            pose=pose_of(msg.pose.pose),
            pose_covariance=planar_covariance(msg.pose.covariance),
            velocity=(msg.twist.twist.linear.x, msg.twist.twist.angular.z),
            velocity_covariance=planar_covariance(msg.twist.covariance),
        )

    def image_and_depth(self) -> tuple[NDArray[np.uint8], NDArray[np.float32] | None]:
        """No depth camera: the frame alone."""
        return self.image(), None

    def image(self) -> NDArray[np.uint8]:
        """The latest frame; black until the first one arrives, and once the latest is
        older than ``STALE_FRAME`` (a camera whose frames stop coming, or are lost on the
        way, must not place the robot again and again where it was)."""
        with self._lock:
            image, age = self._image, time.monotonic() - self._image_at
        if image is None or age > STALE_FRAME:
            return np.zeros((self.camera_model.height, self.camera_model.width), dtype=np.uint8)
        return image


# --- the navigation stack's book -------------------------------------------------------


class StackReadings:
    """What a navigation stack backend knows of its stack: the sub-map it put on ``/map``,
    when it last placed the robot, the pose source's latest pose (counted once stamped
    after that), the planner's latest plan and the goal's progress. Stamps are seconds."""

    def __init__(self) -> None:
        self.map_id: str | None = None
        self._lock = threading.Lock()
        self._placed_at: float | None = None
        self._pose: tuple[float, Pose] | None = None
        self._plan: tuple[int, list[Point]] = (0, [])
        self._progress = ""

    def held(self, map_id: str) -> None:
        """Raises ValueError unless ``map_id`` is the sub-map on ``/map``."""
        if map_id != self.map_id:
            raise ValueError(f"{map_id} is not the map on /map ({self.map_id})")

    def placed(self, stamp: float) -> None:
        with self._lock:
            self._placed_at = stamp

    def on_pose(self, stamp: float, pose: Pose) -> None:
        with self._lock:
            self._pose = (stamp, pose)

    def pose(self) -> Pose | None:
        """The pose source's latest pose, if stamped after the last initial pose."""
        with self._lock:
            placed, found = self._placed_at, self._pose
        if placed is None or found is None or found[0] < placed:
            return None
        return found[1]

    def on_plan(self, points: list[Point]) -> None:
        with self._lock:
            self._plan = (self._plan[0] + 1, points)

    def plan(self) -> tuple[int, Sequence[Point]]:
        with self._lock:
            return self._plan

    def on_progress(self, text: str) -> None:
        with self._lock:
            self._progress = text

    def progress(self) -> str:
        with self._lock:
            return self._progress


def write_map_files(
    map_dir: Path, map_id: str, cells: NDArray[np.int8], resolution: float, origin: Pose
) -> str:
    """The sub-map as map-server files (PGM and YAML) under ``map_dir``; the YAML's path."""
    name = map_id.replace("/", "__")
    meta = MapMetadata(
        f"{name}.pgm", float(resolution), origin, OCCUPIED_THRESH, FREE_THRESH, False
    )
    image, exported = export_map(cells, meta, f"{name}.pgm")
    map_dir.mkdir(parents=True, exist_ok=True)
    (map_dir / f"{name}.pgm").write_bytes(image)
    yaml_path = map_dir / f"{name}.yaml"
    yaml_path.write_text(map_yaml_text(exported))
    return str(yaml_path)


def load_map_files(
    ask: Callable[[str], None] | None,
    map_dir: Path | None,
    map_id: str,
    cells: NDArray[np.int8],
    resolution: float,
    origin: Pose,
) -> None:
    """With a map server (``ask``) and ``map_dir``: the sub-map's map-server files written
    and, off the control loop, ``ask`` called with their YAML's path."""
    if ask is None or map_dir is None:
        return
    url = write_map_files(map_dir, map_id, cells, resolution, origin)
    threading.Thread(target=ask, args=(url,), daemon=True).start()


# --- the node ---------------------------------------------------------------------------


def bridge_parser(
    prog: str, doc: str | None, stack_name: str, action: str, plan_topic: str, load: str
) -> argparse.ArgumentParser:
    """The command line both bridges take (described by ``doc``'s first line), to which
    each adds its own; ``stack_name`` names the ``--navigation`` choice of the robot's own
    stack (``move_base``, ``nav2``) and the flag of its action's name (``--move-base``,
    ``--nav2-action``), ``action`` that name's default, ``load`` what ``--load-map`` is (a
    ``LoadMap`` service's name)."""
    summary = (doc or "").split("\n")[0]
    parser = argparse.ArgumentParser(prog=prog, description=summary)
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
    parser.add_argument("--navigation", choices=(stack_name, "agent"), default=stack_name)
    flag = "--" + stack_name.replace("_", "-") + ("" if stack_name == "move_base" else "-action")
    parser.add_argument(flag, dest="action", default=action, help="the action's name")
    parser.add_argument("--pose-source", default="amcl_pose", help="a pose topic, or tf")
    parser.add_argument("--base-frame", default="base_footprint", help="with tf")
    parser.add_argument("--plan-topic", default=plan_topic)
    parser.add_argument("--load-map", help=load)
    parser.add_argument("--map-dir", type=Path, help="where --load-map's files go")
    parser.add_argument("--log-level", default="INFO")
    return parser


class DriverTopics(TypedDict):
    """The robot's drivers' topics, as both backends' hardware takes them."""

    odom: str
    scan: str
    camera: str
    camera_info: str
    cmd_vel: str


class StackOptions(TypedDict):
    """The navigation stack's settings, as both backends' stacks take them."""

    action: str
    pose_source: str
    base_frame: str
    plan_topic: str
    load_map: str | None
    map_dir: Path


def driver_topics(options: argparse.Namespace) -> DriverTopics:
    return {
        "odom": options.odom,
        "scan": options.scan,
        "camera": options.camera,
        "camera_info": options.camera_info,
        "cmd_vel": options.cmd_vel,
    }


def stack_options(options: argparse.Namespace) -> StackOptions:
    """``map_dir``: where ``LoadMap``'s files go: ``--map-dir``, else a new temporary
    directory."""
    return {
        "action": options.action,
        "pose_source": options.pose_source,
        "base_frame": options.base_frame,
        "plan_topic": options.plan_topic,
        "load_map": options.load_map,
        "map_dir": Path(options.map_dir or tempfile.mkdtemp(prefix="cloudnav-maps-")),
    }


@dataclass
class Bridge:
    """A backend's parts for ``serve``: its hardware (with ``command``), and its
    navigation stack (None: the agent's own planner and controller drive)."""

    hardware: Any
    stack: Any = None


def navigation(bridge: Bridge, options: argparse.Namespace, config: RobotConfig) -> tuple[
    PoseTracker, LegDriver | None
]:  # fmt: skip
    """The pose tracker and leg driver: through the robot's stack, or the agent's own."""
    if bridge.stack is None:
        particles = options.particles
        particles = config.localisation.particles if particles is None else particles
        return PoseTracker(particle_filter(particles, None, config.localisation)), None
    return StackPoseTracker(bridge.stack), StackDriver(bridge.stack, config)


async def serve(options: argparse.Namespace, bridge: Bridge) -> None:
    """Run the robot's software on ``bridge`` and relay to the cloud until SIGINT or
    SIGTERM (or cancelled); on the way out, the stack's goal is cancelled and the robot
    stopped. The cloud going away leaves it running on its held bundles and reconnecting."""
    config = RobotConfig(camera_rate=options.camera_rate)
    http_base, ws_url = endpoints(options.server)
    http = httpx.AsyncClient(
        base_url=http_base, headers={"Authorization": f"Token {options.token}"}, timeout=10.0
    )
    tracker, driver = navigation(bridge, options, config)
    supervisor = MapsSupervisor(BundleCache(http), tracker)
    client = RosbridgeClient(ws_url, options.token)
    robot = Robot(bridge.hardware, supervisor, tracker, client, config, driver=driver)
    declare(robot, client)
    warm_up()
    tasks = [asyncio.create_task(client.run()), asyncio.create_task(robot.run(1.0))]
    stop_on_signals(lambda: [task.cancel() for task in tasks])
    try:
        with contextlib.suppress(asyncio.CancelledError):
            await asyncio.gather(*tasks)
    finally:
        robot.navigator.driver.clear()  # a goal the bridge sent ends with it
        bridge.hardware.command(0.0, 0.0)
        await client.close()
        await http.aclose()


async def run_bridge(
    options: argparse.Namespace, hardware: Callable[[], Any], stack: Callable[[], Any]
) -> None:
    """A backend's node, its ROS client library initialised: the robot's drivers
    (``hardware()``, built off the event loop: it waits for their first messages) and
    navigation stack (``stack()``; none with ``--navigation agent``), then ``serve``."""
    keep_own_logs(options.log_level)
    drivers = await asyncio.to_thread(hardware)
    await serve(options, Bridge(drivers, None if options.navigation == "agent" else stack()))


def run_node(options: argparse.Namespace, main: Coroutine[Any, Any, None]) -> None:
    """Run a backend's ``main`` in a new event loop, logging at ``--log-level``."""
    logging.basicConfig(level=options.log_level, format=LOG_FORMAT)
    asyncio.run(main)


def keep_own_logs(level: str) -> None:
    """Undo what a ROS client library's initialisation does to logging (rospy's replaces
    the root's handlers and disables the loggers that existed before it): the robot's
    software logs to stderr at ``level`` as it did."""
    logging.basicConfig(level=level, format=LOG_FORMAT, force=True)
    for name, found in logging.root.manager.loggerDict.items():
        if name.split(".")[0] in PROJECT_PACKAGES and isinstance(found, logging.Logger):
            found.disabled = False


def stop_on_signals(stop: Callable[[], object]) -> None:
    loop = asyncio.get_running_loop()
    for number in (signal.SIGINT, signal.SIGTERM):
        loop.add_signal_handler(number, stop)
