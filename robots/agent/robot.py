"""One robot's software: tag detector, pose tracking, Maps Supervisor, navigation, and a
rosbridge connection, on its ``hardware`` (``robots.agent.hardware.Hardware``: the
simulator's ``robots.agent.sim.hardware.SimHardware``, or a real robot's bridge).

The software sees only what the hardware reports (odometry, scans, images) and what the
cloud serves; the simulator's ground truth (``SimHardware.true_pose``) exists for its
sensors and for tests, and nothing in ``Robot`` reads it.

Time: the robot lives on a simulated clock advanced in fixed control periods
(``RobotConfig.period``); ``run`` paces it against the wall clock, ``time_scale`` times
faster (tests and demos run faster than real time). Every rate here, and the teleop
watchdog, is in simulated seconds. Messages are stamped ``epoch + simulated seconds``.

Topics (relative names, so the server resolves them to ``/{robot}/...``): publishes
``pose`` (10 Hz, only once the robot knows its sub-map: ``frame_id`` is the Map ID),
``odom`` (10 Hz), ``scan`` (5 Hz), ``plan`` (when it changes), ``nav_status`` (on every
change and at 1 Hz), ``map_id`` (latched, on entering a sub-map and on taking a new version
of it: ``building/code@v<n>``, the version held), ``localisation``
(latched, on every change and at 1 Hz: lost, entering a sub-map or localised, see
``whereabouts``), ``camera/image/compressed`` (``camera_rate``), and
``camera/depth/image/compressedDepth`` with ``camera/camera_info`` (``depth_rate``; also
the raw ``camera/depth/image`` with ``raw_depth``); subscribes
``cmd_vel``, ``goal`` and
``initialpose``; serves ``cancel_goal`` (``std_srvs/Trigger``), which preempts the
active goal. (The server lets operators publish only ``cmd_vel``, ``goal`` and
``initialpose`` to a robot, so a cancel topic could never be published; the service
is what an operator may call.)

Teleop has priority: a ``cmd_vel`` drives the body at once (clamped to its limits) and
navigation stays silent until ``TELEOP_HOLD`` seconds after the last one (a navigation
stack's goal is cancelled meanwhile and sent again after); then the robot sends a stop
itself (the dead-man rule: a teleop command never outlives the commands, even when the
cloud is gone), and the body also stops by itself ``watchdog`` seconds after its last
command, as a TurtleBot does.
"""

from __future__ import annotations

import asyncio
import logging
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Any, Generic, Protocol, TypeVar

import numpy as np
from numpy.typing import NDArray

from cloudnav_core import timecode
from cloudnav_core.messages import (
    Json,
    MappingNews,
    Message,
    battery_state,
    camera_info,
    compressed_depth,
    depth_image,
    goal_of,
    initial_pose_of,
    mapping_news_of,
    path_message,
    pose_stamped,
    status_array,
    string_message,
    twist_of,
    wait_order_of,
)
from cloudnav_core.params import FilterParams, RobotConfig
from cloudnav_core.se2 import Pose, compose, inverse
from cloudnav_core.topics import CANCEL_GOAL, ROBOT_SERVICE_TYPES, ROBOT_TOPIC_TYPES
from robots.agent.client import RosbridgeClient
from robots.agent.depth_scan import seen_obstacles
from robots.agent.hardware import Hardware, compressed_image_message, encode_jpeg
from robots.agent.localisation import ParticleFilter, odometry_delta
from robots.agent.navigation.clearance import LocalObstacles
from robots.agent.navigation.legs import LegDriver
from robots.agent.navigation.navigator import Navigator
from robots.agent.perception import TagDetection, TagDetector, pinhole_calibration
from robots.agent.relocalise import PoseEstimate
from robots.agent.supervisor.maps_supervisor import MapsSupervisor
from robots.agent.supervisor.submaps import BundleError, SubMap
from robots.agent.visual import LOST_SPREAD, TRUSTED_SPREAD, VisualMap, spread
from robots.agent.whereabouts import Whereabouts

logger = logging.getLogger(__name__)

TELEOP_HOLD = 0.5
"""Seconds after a ``cmd_vel`` during which navigation leaves the body alone."""


# --- where the robot is ----------------------------------------------------------------


class Localiser(Protocol):
    """A particle filter's interface (``robots.agent.localisation.ParticleFilter``)."""

    def reset(self, pose: Pose, covariance: NDArray[np.float64]) -> None: ...
    def predict(self, odom_delta: Pose) -> None: ...
    def update(self, scan: Message) -> bool: ...
    def pose(self) -> Pose: ...
    def covariance(self) -> NDArray[np.float64]: ...
    def set_map(self, grid: Any, resolution: float, origin: Pose) -> None: ...


LocaliserFactory = Callable[[SubMap], Localiser]


def particle_filter(
    particles: int, seed: int | None = None, params: FilterParams | None = None
) -> LocaliserFactory | None:
    """A factory of AMCL-like filters with ``params`` (the default robot's without) but
    ``particles`` particles (None for 0: odometry and tags only)."""
    if particles <= 0:
        return None
    base = params or FilterParams()
    fewest = min(base.min_particles, particles)
    chosen = replace(base, particles=particles, min_particles=fewest)

    def make(submap: SubMap) -> Localiser:
        return ParticleFilter(submap.grid, submap.resolution, submap.origin, chosen, seed=seed)

    return make


class PoseTracker:
    """The pose estimate in the current sub-map's frame: odometry composed with the last
    reset (a tag, an operator's initial pose), refined on the laser by a particle filter
    when ``factory`` makes one.

    Before any reset the estimate is the odometry pose itself (the robot is lost; the
    supervisor steers by sight then).
    """

    def __init__(self, factory: LocaliserFactory | None = None) -> None:
        self.factory = factory
        self.filter: Localiser | None = None
        self.odom: Pose = (0.0, 0.0, 0.0)
        self.localised = False
        self._offset: Pose = (0.0, 0.0, 0.0)  # map <- odometry
        self._pending: tuple[Pose, NDArray[np.float64]] | None = None

    def odometry(self, odom: Pose) -> None:
        """A new odometry reading."""
        if self.filter is not None:
            self.filter.predict(odometry_delta(self.odom, odom))
        self.odom = odom

    def scan(self, scan: Json) -> None:
        if self.filter is not None and self.localised:
            self.filter.update(scan)

    def reset(self, pose: Pose, covariance: NDArray[np.float64], at_odom: Pose) -> None:
        """Take ``pose`` as the estimate when odometry read ``at_odom``."""
        now = compose(pose, compose(inverse(at_odom), self.odom))
        self._offset = compose(now, inverse(self.odom))
        self.localised = True
        if self.filter is not None:
            self.filter.reset(now, covariance)
        else:
            self._pending = (now, covariance)

    def set_map(self, submap: SubMap) -> None:
        if self.factory is None:
            return
        if self.filter is None:
            self.filter = self.factory(submap)
            if self._pending is not None:
                self.filter.reset(*self._pending)
        else:
            self.filter.set_map(submap.grid, submap.resolution, submap.origin)
        self._pending = None

    def pose(self) -> Pose:
        if self.filter is not None and self.localised:
            return self.filter.pose()
        return compose(self._offset, self.odom)

    def spread(self) -> float:
        """Metres: the filter's position standard deviation (0 without a filter)."""
        if self.filter is None or not self.localised:
            return 0.0
        return spread(self.filter.covariance())


# --- the robot -------------------------------------------------------------------------


@dataclass(frozen=True)
class Frame:
    """A camera frame, with its registered depth when one was taken."""

    image: NDArray[np.uint8]
    depth: NDArray[np.float32] | None = None


class Publisher(Protocol):
    """Where the robot's messages go: the rosbridge client (a recorder, in tests). ``msg``
    is a message of ``cloudnav_core.messages``."""

    async def publish(self, topic: str, msg: Any) -> bool: ...


H = TypeVar("H", bound=Hardware)


class Robot(Generic[H]):
    """One robot's software on its ``hardware``, talking through ``publisher``."""

    def __init__(
        self,
        hardware: H,
        supervisor: MapsSupervisor,
        tracker: PoseTracker,
        publisher: Publisher,
        config: RobotConfig | None = None,
        epoch: float | None = None,
        visual: VisualMap | None = None,
        driver: LegDriver | None = None,
    ) -> None:
        self.hardware = hardware
        self.visual = visual
        self.supervisor = supervisor
        self.tracker = tracker
        self.publisher = publisher
        self.config = config or RobotConfig()
        self.navigator = Navigator(supervisor, self.config, driver)
        self.detector = TagDetector(hardware.camera_model)
        self.seen = seen_obstacles(hardware.scan_mount, self.config)
        self.epoch = time.time() if epoch is None else epoch
        self._epoch_given = epoch is not None
        self.seconds = 0.0
        self.ticks = 0
        self.detections: list[TagDetection] = []  # the last frame's, for tests and logs
        self._teleop_until = -math.inf
        self._published_plan = 0
        self._published_status = -1
        self._published_whereabouts: Whereabouts | None = None
        self._map_to_publish: str | None = None
        self._mapping_news: MappingNews | None = None
        self._tasks: set[asyncio.Task[Any]] = set()
        self._checking: asyncio.Task[Any] | None = None
        supervisor.on_map.append(self._entered)

    # --- commands from the network -----------------------------------------------------

    def on_cmd_vel(self, msg: Json) -> None:
        """Teleop: drive now; navigation waits ``TELEOP_HOLD`` seconds."""
        twist = twist_of(msg)
        if twist is None:
            return
        self.hardware.command(*twist)
        self._teleop_until = self.seconds + TELEOP_HOLD

    def on_goal(self, msg: Json) -> None:
        """A goal pose in a sub-map (``frame_id`` = its Map ID; a bare map code means this
        building). One it cannot use is rejected on ``nav_status``, saying why."""
        goal = goal_of(msg)
        if goal is None or not goal.map_id.strip():
            reason = _unusable_goal(msg)
            logger.warning("goal rejected: %s", reason)
            self.navigator.reject(reason, self.seconds)
            return
        map_id = goal.map_id
        if "/" not in map_id and self.supervisor.current is not None:
            map_id = f"{self.supervisor.current.building}/{map_id}"
        self.navigator.set_goal(map_id, (goal.x, goal.y, goal.yaw), self.seconds)

    def on_right_of_way(self, msg: Json) -> None:
        """The cloud's right of way: wait at a spot before a narrow place, or go on."""
        self.navigator.give_way(wait_order_of(msg))

    def on_mapping(self, msg: Json) -> None:
        """The cloud's word on mapping this robot, logged when it changes (the latched
        topic says it again on every reconnect): above all why camera frames streamed
        with no session are not mapped."""
        news = mapping_news_of(msg)
        if news is None or news == self._mapping_news:
            return
        self._mapping_news = news
        if news.event == "not_mapping":
            logger.warning("the cloud is not mapping this robot: %s", news.reason)
        elif news.event in ("started", "stopped"):
            logger.info("the cloud's mapping session %s of this robot %s", news.session, news.event)

    def on_initial_pose(self, msg: Json) -> None:
        """An operator's pose estimate, in the sub-map its frame names."""
        found = initial_pose_of(msg)
        if found is None:
            return
        pose, covariance = found
        estimate = PoseEstimate(pose.x, pose.y, pose.yaw, covariance)
        self._spawn(self._relocate(estimate, pose.map_id, self.tracker.odom))

    async def _relocate(self, estimate: PoseEstimate, map_id: str, odom: Pose) -> None:
        try:
            await self.supervisor.relocate(estimate, map_id, odom)
        except BundleError as error:
            logger.warning("initial pose in %s ignored: %s", map_id, error)

    def on_cancel(self, _args: Any) -> Json:
        """The ``cancel_goal`` service: preempt the active goal."""
        cancelled = self.navigator.cancel()
        return {"success": cancelled, "message": "cancelled" if cancelled else "no active goal"}

    async def settle(self) -> None:
        """Return once the work ticks and commands started in the background (bundles
        being fetched) is done; a robot stepped by hand calls it between ticks."""
        await asyncio.gather(*self._tasks)
        await self.supervisor.entered()

    def _entered(self, submap: SubMap) -> None:
        self._map_to_publish = submap.map_ref
        self.detector.sizes.update({m: tag.size for m, tag in submap.tags.items()})

    def _spawn(self, coroutine: Any) -> asyncio.Task[Any]:
        task = asyncio.get_running_loop().create_task(coroutine)
        self._tasks.add(task)
        task.add_done_callback(self._tasks.discard)
        return task

    # --- one control period --------------------------------------------------------------

    async def tick(self) -> None:
        """Advance the body one period, sense, decide, command, publish."""
        self.hardware.advance(self.config.period)
        self.seconds += self.config.period
        self.ticks += 1
        self.tracker.odometry(self.hardware.odom_pose)
        ranges = self.hardware.scan()
        scan = self.hardware.scan_message(ranges, self.stamp)
        self.tracker.scan(scan)
        rates = (self.config.detect_rate, self.config.camera_rate, self.config.depth_rate)
        frame = self._look() if self._due(*rates) else None
        self.supervisor.stand(self.tracker.pose(), self.seconds)
        here = self.hardware.odom_pose
        points = self.seen.update(ranges, self.hardware.scan_angles, here, self.seconds)
        self._drive(LocalObstacles(points, may_enter=self.seen.entry_check(here)))
        self._check_map()
        await self._publish(scan, frame)

    def _check_map(self) -> None:
        """Now and then ask for the sub-map the robot is in again (a conditional request),
        so a new version reaches a robot driving in it; one check at a time."""
        if self._checking is None or self._checking.done():
            self._checking = None
            if self.supervisor.current is not None and self._due(self.config.map_check_rate):
                self._checking = self._spawn(self.supervisor.refresh())

    @property
    def stamp(self) -> float:
        return self.epoch + self.seconds

    def _due(self, *rates: float) -> bool:
        """Whether this tick falls on any of ``rates`` (Hz), counted in ticks."""
        period = self.config.period
        return any(
            rate > 0 and self.ticks % max(1, round(1 / (rate * period))) == 0 for rate in rates
        )

    def _look(self) -> Frame:
        """Render a frame (with depth when due); the detector looks at it when due."""
        depth: NDArray[np.float32] | None = None
        if self._due(self.config.depth_rate):
            image, depth = self.hardware.image_and_depth()
        else:
            image = self.hardware.image()
        if self._due(self.config.detect_rate):
            self.detections = self.detector.detect(image)
            self.supervisor.observe(self.detections, self.tracker.odom, self.seconds)
        if self.visual is not None:
            self._use_visual_map(image, depth)
        return Frame(image, depth)

    # --- the cloud's visual map ---------------------------------------------------------

    def _use_visual_map(self, image: NDArray[np.uint8], depth: NDArray[np.float32] | None) -> None:
        """Send a keyframe when the pose is trustworthy; ask where the robot is when it
        has no sub-map and no marker in sight, or when its filter has lost track."""
        assert self.visual is not None
        current, supervisor = self.supervisor.current, self.supervisor
        if supervisor.entering or supervisor.marker_in_sight(self.seconds):
            return  # a tag is placing the robot: tags win
        if current is None or self.tracker.spread() > LOST_SPREAD:
            if self.visual.may_ask(self.seconds):
                building = current.building if current is not None else ""
                self._spawn(self._wake_up(image, self.tracker.odom, building))
            return
        pose = self.tracker.pose()
        trusted = self.tracker.localised and self.tracker.spread() <= TRUSTED_SPREAD
        if depth is not None and trusted and self.visual.keyframe_due(current.map_id, pose):
            self._spawn(self.visual.send_keyframe(current.map_id, pose, image, depth))

    async def _wake_up(self, image: NDArray[np.uint8], odom: Pose, building: str) -> None:
        assert self.visual is not None
        placement = await self.visual.ask(image, self.seconds, building)
        lost = self.supervisor.current is None or self.tracker.spread() > LOST_SPREAD
        if placement is None or self.supervisor.entering or not lost:
            return  # no answer, or a tag placed the robot meanwhile
        logger.info("placed by the cloud in %s (%d inliers)", placement.map_id, placement.inliers)
        try:
            await self.supervisor.relocate(
                placement.estimate, placement.map_id, odom, "visual relocalisation"
            )
        except BundleError as error:
            logger.warning("cannot enter %s: %s", placement.map_id, error)

    def _drive(self, obstacles: LocalObstacles) -> None:
        if self.seconds < self._teleop_until:
            self.navigator.driver.hold()  # a navigation stack's goal waits for teleop
            return
        if self._teleop_until > -math.inf:
            self._teleop_until = -math.inf
            self.hardware.command(0.0, 0.0)  # the dead-man rule: teleop ends in a stop
        command = self.navigator.step(
            self.tracker.pose(),
            self.tracker.odom,
            self.hardware.reported_velocity,
            obstacles,
            self.seconds,
        )
        if command is not None:
            self.hardware.command(*command)

    # --- publishing --------------------------------------------------------------------

    async def _publish(self, scan: Json, frame: Frame | None) -> None:
        current = self.supervisor.current
        if self._map_to_publish is not None:
            await self.publisher.publish("map_id", string_message(self._map_to_publish))
            self._map_to_publish = None
        if current is not None and self._due(self.config.pose_rate):
            pose = pose_stamped(current.map_id, self.tracker.pose(), self.stamp)
            await self.publisher.publish("pose", pose)
        if self._due(self.config.odom_rate):
            odom = self.hardware.odometry_message(self.stamp)
            await self.publisher.publish("odom", odom)
        if self._due(self.config.scan_rate):
            await self.publisher.publish("scan", scan)
        await self._publish_navigation(current)
        await self._publish_whereabouts()
        if self._due(self.config.status_rate):
            battery = self.hardware.battery
            state = battery_state(battery.charge, battery.voltage, self.stamp)
            await self.publisher.publish("battery", state)
        if frame is not None and self._due(self.config.camera_rate):
            await self._publish_image(frame.image)
        if frame is not None and frame.depth is not None:
            await self._publish_depth(frame.depth)

    async def _publish_navigation(self, current: SubMap | None) -> None:
        driver, board = self.navigator.driver, self.navigator.board
        if driver.plan_version != self._published_plan:
            self._published_plan = driver.plan_version
            frame = current.map_id if current is not None else "odom"
            await self.publisher.publish("plan", path_message(frame, driver.path, self.stamp))
        if board.version != self._published_status or self._due(self.config.status_rate):
            self._published_status = board.version
            await self.publisher.publish("nav_status", status_array(board.entries, self.stamp))

    async def _publish_whereabouts(self) -> None:
        now = self.supervisor.whereabouts()
        if now != self._published_whereabouts or self._due(self.config.status_rate):
            self._published_whereabouts = now
            await self.publisher.publish("localisation", now.status())

    async def _publish_image(self, image: NDArray[np.uint8]) -> None:
        if self.config.camera_timecode:
            # The wall clock, not the simulated one: a viewer compares it with its own.
            image = image.copy()
            timecode.stamp(image, int(time.time() * 1000))
        jpeg = encode_jpeg(image, self.config.jpeg_quality)
        message = compressed_image_message(jpeg, self.stamp)
        await self.publisher.publish("camera/image/compressed", message)

    async def _publish_depth(self, depth: NDArray[np.float32]) -> None:
        frame_id = "camera_optical_frame"
        await self.publisher.publish(DEPTH_TOPIC, compressed_depth(frame_id, depth, self.stamp))
        if self.config.raw_depth:
            await self.publisher.publish(RAW_DEPTH_TOPIC, depth_image(frame_id, depth, self.stamp))
        info = camera_info(frame_id, pinhole_calibration(self.hardware.camera_model), self.stamp)
        await self.publisher.publish("camera/camera_info", info)

    # --- pacing ------------------------------------------------------------------------

    async def run(self, time_scale: float = 1.0) -> None:
        """Tick forever, ``time_scale`` times faster than the wall clock (``inf``: as fast
        as the CPU allows). A robot that falls behind does not rush to catch up."""
        if not self._epoch_given:
            # Stamps start from now, not from when the robot was built (the planner's
            # warm-up came between), so at time scale 1 they follow the wall clock.
            self.epoch = time.time() - self.seconds - self.config.period  # the next tick's
        loop = asyncio.get_running_loop()
        period = self.config.period / time_scale
        next_at = loop.time()
        while True:
            await self.tick()
            next_at += period
            delay = next_at - loop.time()
            if delay < -1.0:
                next_at, delay = loop.time(), 0.0
            await asyncio.sleep(max(delay, 0.0))


def _unusable_goal(msg: Json) -> str:
    """Why ``goal_of`` found no goal in ``msg``, in words for the operator."""
    header = msg.get("header") if isinstance(msg, dict) else None
    frame = header.get("frame_id") if isinstance(header, dict) else None
    if not isinstance(frame, str) or not frame.strip():
        return (
            "the goal names no sub-map: its header.frame_id must be the Map ID "
            "(building/map) of the sub-map it is in"
        )
    return "the goal has no usable pose: its position and orientation must be finite numbers"


# --- declarations on the network -------------------------------------------------------

DEPTH_TOPIC = "camera/depth/image/compressedDepth"
RAW_DEPTH_TOPIC = "camera/depth/image"
PUBLISHED = (
    "pose", "odom", "scan", "plan", "nav_status", "battery", "camera/image/compressed",
    DEPTH_TOPIC, "camera/camera_info",
)  # fmt: skip


def declare(robot: Robot[Any], client: RosbridgeClient) -> None:
    """Advertise ``robot``'s topics, subscribe its commands and serve ``cancel_goal`` on
    ``client``."""
    for topic in PUBLISHED + ((RAW_DEPTH_TOPIC,) if robot.config.raw_depth else ()):
        client.advertise(topic, ROBOT_TOPIC_TYPES[topic])
    for latched in ("map_id", "localisation"):
        client.advertise(latched, ROBOT_TOPIC_TYPES[latched], latch=True)
    client.subscribe("cmd_vel", ROBOT_TOPIC_TYPES["cmd_vel"], robot.on_cmd_vel)
    client.subscribe("goal", ROBOT_TOPIC_TYPES["goal"], robot.on_goal)
    client.subscribe("initialpose", ROBOT_TOPIC_TYPES["initialpose"], robot.on_initial_pose)
    client.subscribe("right_of_way", ROBOT_TOPIC_TYPES["right_of_way"], robot.on_right_of_way)
    client.subscribe("mapping", ROBOT_TOPIC_TYPES["mapping"], robot.on_mapping)
    client.advertise_service(CANCEL_GOAL, ROBOT_SERVICE_TYPES[CANCEL_GOAL], robot.on_cancel)
