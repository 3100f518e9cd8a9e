"""``MapsSupervisor``: which sub-map the robot is in, and what to drive to next on the way
to a goal in another sub-map, tick by tick.

The procedure (the paper's)
===========================

1. No map: turn on the spot until a marker is in view, drive to a point in front of it
   by sight, read its QR code; it names the sub-map the robot is entering.
2. On a decoded tag that leads on (or any tag, when lost): fetch that sub-map's bundle,
   reset the pose from the tag's stored pose and the measured relative pose
   (``relocalise``), make it the current map.
3. Route from the current sub-map to the goal's with ``route_between`` on the bundle's
   topology and its crossings (the server's route endpoint runs the same function on the
   same data, so neither sends a robot along an edge no tag lets it cross), and
   drive to ``APPROACH`` metres in front of the tag leading on, facing it
   (``maps.domain.topology.approach_pose``). Standing there a while without reading it
   (odometry drifted), turn on the spot looking for it. Its QR code read, go to 2.
4. In the goal's sub-map, drive to the goal.

Markers of tags in held bundles also reset the pose whenever seen within
``RESET_RANGE`` (at most every ``RESET_INTERVAL`` seconds): marker ids are unique in a
building, so the marker alone says which stored pose it is, and near the tag the
measured pose is good to a few centimetres. This is what brings a drifted robot onto
the tag it heads for; the QR code still decides which sub-map the robot enters. A tag
whose stored pose no held bundle has (its QR names the sub-map it leads to, whose bundle
holds only its own tags) is looked up in the building's crossings, which every bundle
lists: the bundle of the sub-map it stands in is fetched too. Only a tag that no bundle
the server gives holds cannot place a lost robot: it is passed over and the search goes
on.

A pose estimate standing where no robot can (in a wall, in unknown space beyond one, off
the sub-map) for ``IN_WALL_S`` seconds has gone wrong: the robot counts as lost again and
looks for a tag, rather than planning from inside a wall.
"""

from __future__ import annotations

import asyncio
import logging
import math
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import Protocol

import numpy as np
from numpy.typing import NDArray

from cloudnav_core.grid import cell_of, unstandable
from cloudnav_core.se2 import Pose, compose, inverse
from maps.domain.topology import RouteStep, approach_pose, route_between
from maps.exceptions import MapStoreError
from robots.agent.perception import TagDetection
from robots.agent.relocalise import PoseEstimate, relocalise
from robots.agent.supervisor.bundle_cache import BundleCache
from robots.agent.supervisor.legs import Destination, Leg, LegKind
from robots.agent.supervisor.submaps import BundleError, StoredTag, SubMap
from robots.agent.whereabouts import Localisation, Whereabouts

logger = logging.getLogger(__name__)

SIGHTING_MEMORY = 1.5
"""Seconds a marker sighting steers a lost robot's approach after it was made."""
SIGHTING_RANGE = 2.0
"""Metres: farther marker poses are too noisy to steer by."""
RESET_RANGE = 1.5
"""Metres: markers nearer than this reset the pose (yaw good to a degree or two)."""
RESET_INTERVAL = 0.5
"""Seconds between pose resets from markers seen in passing."""
MAX_AMBIGUITY = 0.05
"""Radians: a marker pose with a mirror solution differing more is not reset from."""
SEARCH_RATE = 0.5
"""Radians per second a searching robot turns."""
SEARCH_TURNS = 1.5
"""Full turns a lost robot makes looking for a tag before it gives up."""
LOOK_AROUND_AFTER = 2.0
"""Seconds at a tag's approach pose without reading it before looking around."""
IN_WALL_S = 2.0
"""Seconds the pose estimate may stand where no robot can before the robot is lost."""


class Relocalisable(Protocol):
    """The robot's pose estimate, as the supervisor resets and re-maps it."""

    def reset(self, pose: Pose, covariance: NDArray[np.float64], at_odom: Pose) -> None:
        """Take ``pose`` (with its 3x3 covariance) as the estimate when odometry read
        ``at_odom``; motion since then is added."""

    def set_map(self, submap: SubMap) -> None:
        """Localise in ``submap`` from now on."""


@dataclass(frozen=True)
class Sighting:
    """A marker seen: its pose in the odometry frame (invariant under pose resets), when,
    and the detection itself."""

    marker: Pose
    seconds: float
    detection: TagDetection


class MapsSupervisor:
    """Decides, tick by tick, which sub-map the robot is in and what its next leg is.

    ``observe`` takes each camera frame's detections; decoded tags that call for it start
    entering a sub-map (in the background: ``leg`` answers HOLD meanwhile). ``leg`` says
    what to drive to now for a ``Destination``. ``on_map`` is called with each sub-map
    entered.
    """

    def __init__(self, cache: BundleCache, tracker: Relocalisable) -> None:
        self.cache = cache
        self.tracker = tracker
        self.current: SubMap | None = None
        self.destination: Destination | None = None
        self.on_map: list[Callable[[SubMap], None]] = []
        self._sightings: dict[int, Sighting] = {}
        self._last_reset = -math.inf
        self._useless: set[int] = set()  # markers no held bundle can place a lost robot by
        self._entering: asyncio.Task[None] | None = None
        self._entering_by: Whereabouts | None = None
        self.placed_by = ""  # what made the current sub-map current: "tag 3", "initial pose"
        self._arrived_at: float | None = None
        self._searched_from: float | None = None  # when the current search began
        self._unstandable_since: float | None = None  # the estimate where no robot can be

    # --- perception ----------------------------------------------------------------------

    def observe(self, detections: Iterable[TagDetection], odom: Pose, seconds: float) -> None:
        """Record what the camera saw at odometry pose ``odom``; act on decoded tags,
        reset the pose from near markers."""
        for detection in sorted(detections, key=lambda d: d.distance):
            marker = compose(odom, detection.base_pose())
            self._sightings[detection.marker_id] = Sighting(marker, seconds, detection)
            if self.entering:
                continue
            if detection.payload is not None and self._enters(detection):
                self._start_entering(detection, odom)
            elif self._may_reset(detection, seconds):
                assert self.current is not None
                if self._reset_from(detection, odom, self.current):
                    self._last_reset = seconds

    def _enters(self, detection: TagDetection) -> bool:
        """Whether this decoded tag takes the robot into the sub-map it names: any tag
        when lost, else the one it is heading for (naming another sub-map)."""
        if self.current is None:
            return detection.marker_id not in self._useless
        named = _named(detection)
        return detection.marker_id == self._leading_tag() and named != self.current.map_id

    def _may_reset(self, detection: TagDetection, seconds: float) -> bool:
        return (
            self.current is not None
            and detection.distance <= RESET_RANGE
            and detection.ambiguity <= MAX_AMBIGUITY
            and seconds - self._last_reset >= RESET_INTERVAL
        )

    def stand(self, pose: Pose, seconds: float) -> None:
        """The pose estimate now: one where no robot can stand for ``IN_WALL_S`` seconds
        makes the robot lost (see the module)."""
        held = self.current
        if held is None or self.entering:
            self._unstandable_since = None
            return
        why = unstandable(held.grid, cell_of(pose[:2], held.origin, held.resolution))
        if not why:
            self._unstandable_since = None
        elif self._unstandable_since is None:
            self._unstandable_since = seconds
        elif seconds - self._unstandable_since >= IN_WALL_S:
            logger.warning(
                "pose estimate (%.2f, %.2f) %s of %s for %.0f s: lost, looking for a tag",
                pose[0],
                pose[1],
                why,
                held.map_id,
                IN_WALL_S,
            )
            self.lose()

    def lose(self) -> None:
        """Hold no sub-map: the robot is lost until a tag (or the cloud) places it."""
        self.current = None
        self.placed_by = ""
        self._unstandable_since = None
        self._arrived_at = None
        self._searched_from = None

    # --- entering a sub-map ----------------------------------------------------------------

    @property
    def entering(self) -> bool:
        return self._entering is not None and not self._entering.done()

    async def entered(self) -> None:
        """Return once no sub-map is being entered."""
        if self._entering is not None:
            await self._entering

    def _start_entering(self, detection: TagDetection, odom: Pose) -> None:
        map_id, source = _named(detection), f"tag {detection.marker_id}"
        logger.info("%s read: entering %s", source, map_id)
        self._entering_by = Whereabouts(Localisation.ENTERING, map_id, source)
        self._entering = asyncio.create_task(self._enter(map_id, detection, odom))

    def whereabouts(self) -> Whereabouts:
        """Whether the robot knows where it is, and by what (the ``localisation`` topic)."""
        if self.entering and self._entering_by is not None:
            return self._entering_by
        if self.current is None:
            return Whereabouts(Localisation.LOST)
        return Whereabouts(Localisation.LOCALISED, self.current.map_id, self.placed_by)

    async def _enter(self, map_id: str, detection: TagDetection, odom: Pose) -> None:
        """Fetch ``map_id``, reset the pose from ``detection``, make it current. On
        failure nothing changes: the next reading of the tag tries again."""
        try:
            submap = await self.cache.load(map_id)
        except BundleError as error:
            logger.warning("cannot enter %s: %s", map_id, error)
            return
        if self.cache.find_tag(submap.building, detection.marker_id, submap) is None:
            await self._fetch_home(detection.marker_id, submap)
        if not self._reset_from(detection, odom, submap) and self.current is None:
            logger.warning(
                "tag %d is in no held bundle: it cannot place the robot", detection.marker_id
            )
            self._useless.add(detection.marker_id)
            return
        self.make_current(submap, f"tag {detection.marker_id}")

    async def _fetch_home(self, marker_id: int, submap: SubMap) -> None:
        """Fetch the bundle of the sub-map tag ``marker_id`` stands in, as ``submap``'s
        crossings say, so that its stored pose is held; a failure leaves it unheld."""
        home = next((c.submap for c in submap.crossings or () if c.marker_id == marker_id), None)
        if home is None:
            return
        try:
            await self.cache.load(f"{submap.building}/{home}")
        except BundleError as error:
            logger.warning("cannot fetch the map tag %d stands in: %s", marker_id, error)

    def _reset_from(self, detection: TagDetection, odom: Pose, submap: SubMap) -> bool:
        """Reset the pose from a tag held in some bundle; False if none holds it."""
        stored = self.cache.find_tag(submap.building, detection.marker_id, submap)
        if stored is None:
            return False
        estimate = relocalise(stored, detection)
        self.tracker.reset((estimate.x, estimate.y, estimate.yaw), estimate.covariance, odom)
        return True

    def make_current(self, submap: SubMap, placed_by: str = "the map it was given") -> None:
        """Localise and plan in ``submap`` from now on; ``placed_by`` says what put it
        there."""
        self.current = submap
        self.placed_by = placed_by
        self.tracker.set_map(submap)
        self._arrived_at = None
        for callback in self.on_map:
            callback(submap)

    async def refresh(self) -> bool:
        """Ask the server again, conditionally, for the sub-map the robot is in; a new
        version of it becomes current at once (same frame, so the pose estimate stands;
        plans are made again on it). Returns whether the map changed. Unreachable servers
        and unreadable answers leave everything as it was."""
        held = self.current
        if held is None or self.entering:
            return False
        try:
            fresh = await self.cache.load(held.map_id)
        except BundleError as error:
            logger.warning("cannot check %s for a new version: %s", held.map_id, error)
            return False
        if fresh is held or self.current is not held or self.entering:
            return False
        logger.info("%s: version %s replaces %s", held.map_id, fresh.revision, held.revision)
        self.current = fresh
        self.tracker.set_map(fresh)
        for callback in self.on_map:
            callback(fresh)
        return True

    async def relocate(
        self, estimate: PoseEstimate, map_id: str, odom: Pose, placed_by: str = "initial pose"
    ) -> None:
        """A pose in ``map_id`` from outside (an operator's initial pose, the cloud's
        visual relocalisation) when odometry read ``odom``: fetch that map, reset there.
        Raises BundleError when the map cannot be had."""
        submap = await self.cache.load(map_id)
        pose = (estimate.x, estimate.y, estimate.yaw)
        self.tracker.reset(pose, estimate.covariance, odom)
        self.make_current(submap, placed_by)

    def marker_in_sight(self, seconds: float) -> bool:
        """Whether a usable marker was seen lately (a tag beats asking the cloud)."""
        return any(
            m not in self._useless and self._fresh(s, seconds) for m, s in self._sightings.items()
        )

    # --- legs ------------------------------------------------------------------------------

    def set_destination(self, destination: Destination | None) -> None:
        self.destination = destination
        self._arrived_at = None
        self._searched_from = None

    def leg(self, pose: Pose, odom: Pose, seconds: float) -> Leg:
        """The leg toward the destination, given the pose estimate and odometry now."""
        leg = self._next_leg(pose, odom, seconds)
        if leg.kind is not LegKind.SEARCH:
            self._searched_from = None
        return leg

    def _next_leg(self, pose: Pose, odom: Pose, seconds: float) -> Leg:
        if self.entering:
            return Leg(LegKind.HOLD, "reading the map of the sub-map entered")
        if self.destination is None:
            return Leg(LegKind.HOLD, "no goal")
        if self.current is None:
            return self._lost_leg(pose, odom, seconds)
        if self.destination.building != self.current.building:
            return Leg(LegKind.FAIL, f"{self.destination.building} is not this building")
        if self.destination.code == self.current.code:
            text = f"driving to the goal in {self.current.map_id}"
            return Leg(LegKind.FINAL, text, self.destination.pose, submap=self.current)
        return self._tag_leg(seconds)

    def route(self, goal_code: str) -> list[RouteStep]:
        """The sub-maps from the current one to ``goal_code``, with the tags leading on.
        Raises TopologyError, NoRouteError (``route_between``) or BundleError (no map)."""
        if self.current is None:
            raise BundleError("no sub-map held yet")
        current = self.current
        links = current.crossings
        if links is None:  # an older server: the tags of the bundles held are all it knows
            links = tuple(self.cache.tag_links(current.building))
        return route_between(current.nodes, current.edges, links, current.code, goal_code)

    def _leading_tag(self) -> int | None:
        """Marker id of the tag leading on toward the destination, if any."""
        if self.destination is None or self.current is None:
            return None
        try:
            first = self.route(self.destination.code)[0]
        except (MapStoreError, BundleError):
            return None
        return first.tag.marker_id if first.tag is not None else None

    def _tag_leg(self, seconds: float) -> Leg:
        assert self.current is not None
        assert self.destination is not None
        try:
            steps = self.route(self.destination.code)
        except MapStoreError as error:
            return Leg(LegKind.FAIL, str(error))
        tag = steps[0].tag
        stored = None if tag is None else self.current.tags.get(tag.marker_id)
        if tag is None or stored is None:
            return Leg(LegKind.FAIL, f"no tag leads from {steps[0].submap} to {steps[1].submap}")
        return self._approach_leg(stored, seconds)

    def _approach_leg(self, tag: StoredTag, seconds: float) -> Leg:
        """Drive in front of ``tag``; look around when standing there a while without
        reading it."""
        assert self.current is not None
        text = f"to tag {tag.marker_id}, leading to {tag.links_to}"
        if self._recent(tag.marker_id, seconds) is not None:
            self._arrived_at = None  # in sight again: the resets have put it right
        if self._arrived_at is not None and seconds - self._arrived_at > LOOK_AROUND_AFTER:
            if self._searched_too_long(seconds):
                return Leg(LegKind.FAIL, f"tag {tag.marker_id} is not where the map has it")
            return Leg(LegKind.SEARCH, f"looking around for tag {tag.marker_id}")
        target = approach_pose((tag.x, tag.y, tag.yaw))
        return Leg(LegKind.APPROACH, text, target, tag.marker_id, submap=self.current)

    def arrived(self, seconds: float) -> None:
        """The robot stands at an approach pose (the tag not read yet)."""
        if self._arrived_at is None:
            self._arrived_at = seconds

    def _lost_leg(self, pose: Pose, odom: Pose, seconds: float) -> Leg:
        """No map yet: approach the nearest marker in sight, else turn looking for one."""
        usable = [
            s
            for m, s in self._sightings.items()
            if m not in self._useless and self._fresh(s, seconds)
        ]
        if usable:
            nearest = min(usable, key=lambda s: s.detection.distance)
            target = approach_pose(to_frame(nearest.marker, pose, odom))
            marker = nearest.detection.marker_id
            return Leg(LegKind.APPROACH, f"to tag {marker}, to read it", target, marker)
        if self._searched_too_long(seconds):
            return Leg(LegKind.FAIL, "no tag in sight")
        return Leg(LegKind.SEARCH, "looking for a tag")

    def _searched_too_long(self, seconds: float) -> bool:
        """Whether the robot has been searching for ``SEARCH_TURNS`` turns' time."""
        if self._searched_from is None:
            self._searched_from = seconds
        return seconds - self._searched_from > SEARCH_TURNS * 2 * math.pi / SEARCH_RATE

    def _recent(self, marker_id: int, seconds: float) -> Sighting | None:
        sighting = self._sightings.get(marker_id)
        return sighting if sighting is not None and self._fresh(sighting, seconds) else None

    @staticmethod
    def _fresh(sighting: Sighting, seconds: float) -> bool:
        close = sighting.detection.distance <= SIGHTING_RANGE
        return close and seconds - sighting.seconds <= SIGHTING_MEMORY


# --- names and poses --------------------------------------------------------------------


def _named(detection: TagDetection) -> str:
    """The Map ID a decoded tag's QR names."""
    assert detection.payload is not None
    return f"{detection.payload.building_code}/{detection.payload.map_code}"


def to_frame(in_odom: Pose, pose: Pose, odom: Pose) -> Pose:
    """A pose known in the odometry frame, in the estimate's frame, given the estimate
    ``pose`` and odometry ``odom`` of the same instant."""
    return compose(pose, compose(inverse(odom), in_odom))
