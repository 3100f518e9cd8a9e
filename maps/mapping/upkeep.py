"""Map upkeep in the server process the robots are connected to: laser evidence per
sub-map from robots navigating normally, proposals for admins, and accepting them.

``UpkeepRunner`` taps every connected robot's ``pose`` (its estimate, ``frame_id`` = the
Map ID) and ``scan``, and pairs each scan with the pose of *its own time stamp*: the
robot's clock, whatever it says against the server's (a loaded robot's runs behind). A
pose is not always there when its scan comes: a congested robot drops telemetry, and a
ROS robot's AMCL publishes the pose of a scan after the scan. So the last
``POSES_KEPT`` poses are kept, a scan newer than all of them waits (``PENDING_SCANS`` at
most) for its pose, and a scan whose pose never comes (none within ``PAIR_WITHIN``
seconds of its stamp) is not used (``unpaired``): the latest pose is not the pose of the
scan, and a scan a turn's worth off made the fleet propose walls that were there.

A paired scan taken ``MIN_MOVE`` from the last one is queued (an ``Inbox`` that drops
the oldest when the worker falls behind, counted in ``dropped``), and the upkeep's
worker thread (``cloudnav_core.workers``, stopped at shutdown) adds it to the
evidence (``maps.domain.upkeep.Evidence``) of that sub-map's current version, which
uses only scans whose pose the stored map confirms and never frees the wall a tag hangs
on. A robot leaving the sub-map, or ``PASS_SECONDS`` of its own scans (by its stamps),
ends that robot's pass. Every ``SAVE_EVERY`` seconds a non-empty proposal is written as
the sub-map's open ``ChangeProposal`` for that version, with the passes and the robots
that saw each cell; a new version of the sub-map starts its evidence again.

``edit`` replaces an open proposal's cells with the ones an admin painted (occupied,
free, unknown); the fleet's evidence no longer rewrites an edited proposal. ``accept``
makes a proposal (or the part of it an admin kept) the sub-map's next version
(reason ``change``); one made on a version that is no longer current is refused with
``VersionConflict`` and nothing changes.
"""

from __future__ import annotations

import asyncio
import logging
import math
import time
from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from django.db import transaction

from cloudnav_core.messages import published_pose_of
from cloudnav_core.times import stamp_seconds
from cloudnav_core.workers import Inbox, Policy, Pool, TaskWorker

from .. import services, versions
from ..domain.mapfile import export_map, load_map_upload, map_yaml_text
from ..domain.slam.scans import Scan
from ..domain.upkeep import Evidence, Proposal
from ..domain.versions import Reason
from ..exceptions import MappingError
from ..models import Building, ChangeProposal, SubMap, SubMapVersion
from .runner import OnMessage, Tap, TopicTaps

logger = logging.getLogger(__name__)

POLL = 2.0
QUEUE_SCANS = 50
MIN_MOVE = 0.2
"""Metres (or radians / 2) a robot moves between the scans taken: evidence needs views
from places, not every scan, and the relay's robots may scan fast in simulated time."""
PASS_SECONDS = 60.0
"""Seconds of a robot's own clock (its scans' stamps) after which its pass ends."""
SAVE_EVERY = 5.0
POSES_KEPT = 50
"""Poses kept per robot to pair scans with (5 s at 10 Hz)."""
PENDING_SCANS = 10
"""Scans kept per robot waiting for the pose of their stamp."""
PAIR_WITHIN = 0.02
"""Seconds: a pose pairs with a scan when their stamps are this close (the robot stamps
a scan and the pose it gives for it alike)."""

_EXECUTOR = Pool("upkeep", 1).executor  # stopped and joined at the end (the registry)

Placed = tuple[str, tuple[float, float, float]]
"""A pose estimate: the Map ID and (x, y, yaw) in it."""
Queued = tuple[
    str, str, tuple[float, float, float], float, dict[str, Any], list[tuple[float, float]]
]
"""A scan waiting for the worker: robot, Map ID, pose estimate, stamp, the message, and
where the other robots in that sub-map last said they were."""


@dataclass
class _Robot:
    name: str
    poses: deque[tuple[float, Placed]] = field(default_factory=lambda: deque(maxlen=POSES_KEPT))
    pending: deque[tuple[float, dict[str, Any]]] = field(
        default_factory=lambda: deque(maxlen=PENDING_SCANS)
    )
    taken: Placed | None = None  # where the last scan was
    taps: list[Tap] = field(default_factory=list)

    def pose_at(self, stamp: float) -> Placed | None:
        """The pose stamped within ``PAIR_WITHIN`` of ``stamp``, the nearest (the newest
        of equals); or None."""
        best: Placed | None = None
        gap = math.inf
        for when, placed in reversed(self.poses):
            if abs(when - stamp) <= PAIR_WITHIN and abs(when - stamp) < gap:
                best, gap = placed, abs(when - stamp)
        return best


@dataclass
class _MapEvidence:
    submap_pk: int
    revision: int
    evidence: Evidence
    pass_started: dict[str, float] = field(default_factory=dict)  # robot -> its stamp


class UpkeepRunner:
    """Evidence about the stored sub-maps from the robots connected to this process."""

    def __init__(self, hub: TopicTaps) -> None:
        self.hub = hub
        self.robots: dict[str, _Robot] = {}
        self.queue: Inbox[Queued] = Inbox("upkeep scans", QUEUE_SCANS, Policy.DROP_OLDEST)
        self._worker = TaskWorker("map upkeep", self._run)
        self.unpaired = 0  # scans whose pose never came
        self.maps: dict[str, _MapEvidence] = {}
        self._where: dict[str, str] = {}  # robot -> Map ID it last scanned in
        # Map ID -> robot -> (x, y) it last said it was at there; robot -> that Map ID
        self._standing: dict[str, dict[str, tuple[float, float]]] = {}
        self._standing_in: dict[str, str] = {}
        self._saved_at = time.monotonic()

    @property
    def dropped(self) -> int:
        """Scans the worker fell too far behind to take (the oldest go first)."""
        return self.queue.dropped

    def start(self) -> None:
        self._worker.start()

    async def _run(self) -> None:
        loop = asyncio.get_running_loop()
        while True:
            self.sync_taps()
            batch = self.queue.take_all()
            try:
                if batch:
                    await loop.run_in_executor(_EXECUTOR, self.process, batch)
                if time.monotonic() - self._saved_at >= SAVE_EVERY:
                    self._saved_at = time.monotonic()
                    await loop.run_in_executor(_EXECUTOR, self.save)
            except Exception:
                logger.exception("map upkeep: a batch failed; going on with the next")
            await asyncio.sleep(POLL)

    # --- taps: on the hot path, a few look-ups ---------------------------------------

    def sync_taps(self) -> None:
        here = self.hub.robots()
        for name in list(self.robots):
            if name not in here:
                for tap in self.robots.pop(name).taps:
                    tap.close()
                self._stand(name, None)
        for name in here - self.robots.keys():
            robot = self.robots[name] = _Robot(name)
            robot.taps = [
                self.hub.tap(f"/{name}/pose", self._on_pose(robot)),
                self.hub.tap(f"/{name}/scan", self._on_scan(robot)),
            ]

    def _on_pose(self, robot: _Robot) -> OnMessage:
        def on_pose(_topic: object, msg: dict[str, Any]) -> None:
            found, stamp = published_pose_of(msg), stamp_seconds(msg)
            if found is None or stamp is None or not found.map_id:
                return
            if not math.isfinite(found.x + found.y + found.yaw):
                return
            robot.poses.append((stamp, (found.map_id, (found.x, found.y, found.yaw))))
            self._stand(robot.name, found.map_id, (found.x, found.y))
            self._pair_pending(robot, stamp)

        return on_pose

    def _on_scan(self, robot: _Robot) -> OnMessage:
        def on_scan(_topic: object, msg: dict[str, Any]) -> None:
            stamp = stamp_seconds(msg)
            if stamp is None:
                self.unpaired += 1
                return
            placed = robot.pose_at(stamp)
            if placed is not None:
                self._take(robot, placed, stamp, msg)
            elif not robot.poses or stamp > robot.poses[-1][0]:
                if len(robot.pending) == robot.pending.maxlen:
                    self.unpaired += 1
                robot.pending.append((stamp, msg))  # its pose may come after it
            else:
                self.unpaired += 1

        return on_scan

    def _pair_pending(self, robot: _Robot, newest: float) -> None:
        """Take the waiting scans the poses now pair; forget those whose pose is past."""
        while robot.pending and robot.pending[0][0] <= newest + PAIR_WITHIN:
            stamp, msg = robot.pending.popleft()
            placed = robot.pose_at(stamp)
            if placed is None:
                self.unpaired += 1
            else:
                self._take(robot, placed, stamp, msg)

    def _take(self, robot: _Robot, placed: Placed, stamp: float, msg: dict[str, Any]) -> None:
        if not _moved(robot.taken, placed):
            return
        robot.taken = placed
        others = self._others_in(placed[0], robot)
        self.queue.put((robot.name, placed[0], placed[1], stamp, msg, others))

    def _stand(self, name: str, map_id: str | None, at: tuple[float, float] = (0.0, 0.0)) -> None:
        """Note that robot ``name`` last said it was ``at`` in ``map_id`` (None: it left)."""
        before = self._standing_in.pop(name, None)
        if before is not None:
            self._standing[before].pop(name, None)
        if map_id is not None:
            self._standing_in[name] = map_id
            self._standing.setdefault(map_id, {})[name] = at

    def _others_in(self, map_id: str, robot: _Robot) -> list[tuple[float, float]]:
        """Where the other robots in sub-map ``map_id`` last said they were: what their
        bodies return is not the map (a robot waiting in a doorway was proposed as a
        new obstacle). A look-up of that sub-map's robots, not a pass over the fleet."""
        return [at for name, at in self._standing.get(map_id, {}).items() if name != robot.name]

    # --- the worker thread -------------------------------------------------------------

    def process(self, batch: Sequence[Queued]) -> None:
        for robot, map_id, pose, stamp, msg, others in batch:
            left = self._where.get(robot)
            if left is not None and left != map_id and left in self.maps:
                self._end_pass(self.maps[left], robot)  # the robot left that sub-map
            self._where[robot] = map_id
            held = self._evidence(map_id)
            if held is None:
                continue
            try:
                scan = Scan.from_message(msg)
            except ValueError:
                continue
            held.evidence.add(pose, scan, robot, others)
            if stamp - held.pass_started.setdefault(robot, stamp) >= PASS_SECONDS:
                self._end_pass(held, robot)

    @staticmethod
    def _end_pass(held: _MapEvidence, robot: str) -> None:
        held.evidence.end_pass(robot)
        held.pass_started.pop(robot, None)

    def _evidence(self, map_id: str) -> _MapEvidence | None:
        held = self.maps.get(map_id)
        if held is not None:
            return held
        building, _, code = map_id.partition("/")
        submap = SubMap.objects.filter(building__code=building, code=code).first()
        if submap is None:
            return None
        grid = services.grid_of(submap)
        tags = [(x, y, yaw) for x, y, yaw in submap.tags.values_list("x", "y", "yaw")]
        origin = (submap.origin_x, submap.origin_y)
        evidence = Evidence(grid, origin, submap.resolution, tags=tags)
        held = self.maps[map_id] = _MapEvidence(submap.pk, submap.revision, evidence)
        return held

    def save(self) -> None:
        """Write each sub-map's proposal; forget the evidence of replaced versions."""
        for map_id, held in list(self.maps.items()):
            current = (
                SubMap.objects.filter(pk=held.submap_pk).values_list("revision", flat=True).first()
            )
            if current != held.revision:
                del self.maps[map_id]  # a new version (or none): evidence starts again
                continue
            proposal = held.evidence.proposal()
            if not proposal.empty:
                store_proposal(held.submap_pk, held.revision, proposal, held.evidence.scans)


def _moved(before: Placed | None, now: Placed) -> bool:
    if before is None or before[0] != now[0]:
        return True
    (x0, y0, a0), (x1, y1, a1) = before[1], now[1]
    turned = abs(math.remainder(a1 - a0, math.tau))
    return math.hypot(x1 - x0, y1 - y0) + turned / 2 >= MIN_MOVE


def store_proposal(submap_pk: int, revision: int, proposal: Proposal, scans: int) -> None:
    """Create or update the open proposal for version ``revision`` of the sub-map, unless
    an admin edited it (their edit stands)."""
    open_ = ChangeProposal.objects.filter(
        submap_id=submap_pk, based_on=revision, state=ChangeProposal.OPEN
    )
    if open_.filter(edited=True).exists():
        return
    ChangeProposal.objects.update_or_create(
        submap_id=submap_pk,
        based_on=revision,
        state=ChangeProposal.OPEN,
        defaults={
            "added": proposal.added.tolist(),
            "removed": proposal.removed.tolist(),
            "added_passes": proposal.added_passes.tolist(),
            "removed_passes": proposal.removed_passes.tolist(),
            "added_robots": proposal.added_robots.tolist(),
            "removed_robots": proposal.removed_robots.tolist(),
            "passes": proposal.passes,
            "robots": proposal.robots,
            "scans": scans,
        },
    )


@transaction.atomic
def edit(
    proposal: ChangeProposal,
    added: list[list[int]],
    removed: list[list[int]],
    unknown: list[list[int]],
) -> ChangeProposal:
    """Replace an open proposal's cells by an admin's (cells of its version, checked by
    the caller); a cell keeps the passes the fleet saw it on if it stays as proposed, 0
    otherwise, and the robots likewise. Raises MappingError for a proposal no longer
    open."""
    locked = ChangeProposal.objects.select_for_update().get(pk=proposal.pk)
    if locked.state != ChangeProposal.OPEN:
        raise MappingError(f"This proposal is {locked.state}.")
    locked.added_passes = _passes_of(added, locked.added, locked.added_passes)
    locked.removed_passes = _passes_of(removed, locked.removed, locked.removed_passes)
    locked.added_robots = _passes_of(added, locked.added, locked.added_robots)
    locked.removed_robots = _passes_of(removed, locked.removed, locked.removed_robots)
    locked.added, locked.removed, locked.unknown = added, removed, unknown
    locked.edited = True
    locked.save()
    return locked


def _passes_of(cells: list[list[int]], proposed: list[list[int]], passes: list[int]) -> list[int]:
    """The count (passes, robots) of each cell as proposed, 0 for a cell not proposed
    (or proposed before the count was kept)."""
    if len(passes) != len(proposed):
        passes = [0] * len(proposed)
    seen = {(int(r), int(c)): int(n) for (r, c), n in zip(proposed, passes, strict=True)}
    return [seen.get((r, c), 0) for r, c in cells]


@transaction.atomic
def accept(
    proposal: ChangeProposal,
    by: Any = None,
    added: list[list[int]] | None = None,
    removed: list[list[int]] | None = None,
) -> SubMapVersion:
    """Make the proposal the sub-map's next version; ``added`` and ``removed`` (cells of
    the proposal an admin kept) replace its own when given. Raises MappingError for a
    proposal no longer open, VersionConflict when the sub-map moved past its version."""
    locked = ChangeProposal.objects.select_for_update().get(pk=proposal.pk)
    if locked.state != ChangeProposal.OPEN:
        raise MappingError(f"This proposal is {locked.state}.")
    submap = locked.submap
    keep_added = _kept(locked.added, added)
    keep_removed = _kept(locked.removed, removed)
    grid = services.grid_of(versions.version_of(submap, locked.based_on))
    change = Proposal(
        _cell_array(keep_added),
        _cell_array(keep_removed),
        np.zeros(0, np.uint16),
        np.zeros(0, np.uint16),
        locked.passes,
        _cell_array(locked.unknown),
    )
    meta = services.metadata_of(submap)
    pgm, exported = export_map(change.applied_to(grid), meta, f"{submap.code}.pgm")
    loaded = load_map_upload(map_yaml_text(exported).encode(), {exported.image: pgm}, 10**8)
    note = (
        f"{len(keep_added)} cells became occupied, {len(keep_removed)} free"
        + (f", {len(locked.unknown)} unknown (edited)" if locked.edited else "")
        + f" ({locked.passes} passes)"
    )
    made = versions.publish(submap, loaded, Reason.CHANGE, locked.based_on, by, note)
    person = by if getattr(by, "is_authenticated", False) and by.pk else None
    ChangeProposal.objects.filter(pk=locked.pk).update(
        state=ChangeProposal.ACCEPTED, decided_by=person, version=made.number
    )
    return made


def reject(proposal: ChangeProposal, by: Any = None) -> None:
    person = by if getattr(by, "is_authenticated", False) and by.pk else None
    updated = ChangeProposal.objects.filter(pk=proposal.pk, state=ChangeProposal.OPEN).update(
        state=ChangeProposal.REJECTED, decided_by=person
    )
    if not updated:
        raise MappingError("This proposal is no longer open.")


def _cell_array(cells: list[list[int]]) -> Any:
    return np.array(cells, dtype=np.intp).reshape(-1, 2)


def _kept(proposed: list[list[int]], kept: list[list[int]] | None) -> list[list[int]]:
    """The proposed cells an admin kept (all when they named none); cells not proposed
    are ignored."""
    if kept is None:
        return proposed
    allowed = {tuple(cell) for cell in proposed}
    return [list(cell) for cell in kept if tuple(cell) in allowed]


def proposals_of(building: Building, code: str) -> Any:
    return ChangeProposal.objects.filter(submap__building=building, submap__code=code)
