"""Map upkeep in the server process the robots are connected to: laser evidence per
sub-map from robots navigating normally, proposals for admins, and accepting them.

``UpkeepRunner`` taps every connected robot's ``pose`` (its estimate, ``frame_id`` = the
Map ID) and ``scan``; a scan taken ``MIN_MOVE`` from the last one is queued with the
robot's latest pose (a bounded queue:
the oldest is dropped when the worker falls behind), and a worker thread adds it to the
evidence (``maps.domain.upkeep.Evidence``) of that sub-map's current version, which
uses only scans whose pose the stored map confirms. A robot leaving the sub-map, or
``PASS_SECONDS`` of scans, ends a pass. Every ``SAVE_EVERY`` seconds a non-empty proposal
is written as the sub-map's open ``ChangeProposal`` for that version; a new version of
the sub-map starts its evidence again.

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
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from django.db import transaction

from telemetry.domain.bus import OnMessage, Topic
from telemetry.domain.messages import pose_of

from .. import services, versions
from ..domain.mapfile import export_map, load_map_upload, map_yaml_text
from ..domain.slam import Scan
from ..domain.upkeep import Evidence, Proposal
from ..domain.versions import Reason
from ..exceptions import MappingError
from ..models import Building, ChangeProposal, SubMap, SubMapVersion
from .runner import Tap, TopicTaps

logger = logging.getLogger(__name__)

POLL = 2.0
QUEUE_SCANS = 50
MIN_MOVE = 0.2
"""Metres (or radians / 2) a robot moves between the scans taken: evidence needs views
from places, not every scan, and the relay's robots may scan fast in simulated time."""
PASS_SECONDS = 60.0
SAVE_EVERY = 5.0

_EXECUTOR = ThreadPoolExecutor(max_workers=1, thread_name_prefix="upkeep")


Queued = tuple[str, str, tuple[float, float, float], dict[str, Any]]
"""A scan waiting for the worker: robot, Map ID, pose estimate, the message."""


@dataclass
class _Robot:
    name: str
    pose: tuple[str, tuple[float, float, float]] | None = None
    taken: tuple[str, tuple[float, float, float]] | None = None  # where the last scan was
    taps: list[Tap] = field(default_factory=list)


@dataclass
class _MapEvidence:
    submap_pk: int
    revision: int
    evidence: Evidence
    pass_started: float
    visitors: set[str] = field(default_factory=set)


class UpkeepRunner:
    """Evidence about the stored sub-maps from the robots connected to this process."""

    def __init__(self, hub: TopicTaps) -> None:
        self.hub = hub
        self.robots: dict[str, _Robot] = {}
        self.queue: deque[Queued] = deque(maxlen=QUEUE_SCANS)
        self.dropped = 0
        self.maps: dict[str, _MapEvidence] = {}
        self._where: dict[str, str] = {}  # robot -> Map ID it last scanned in
        self._saved_at = time.monotonic()

    def start(self) -> None:
        asyncio.get_running_loop().create_task(self._run())

    async def _run(self) -> None:
        loop = asyncio.get_running_loop()
        while True:
            self.sync_taps()
            batch = list(self.queue)
            self.queue.clear()
            try:
                if batch:
                    await loop.run_in_executor(_EXECUTOR, self.process, batch)
                if time.monotonic() - self._saved_at >= SAVE_EVERY:
                    self._saved_at = time.monotonic()
                    await loop.run_in_executor(_EXECUTOR, self.save)
            except Exception:
                logger.exception("map upkeep: a batch failed; going on with the next")
            await asyncio.sleep(POLL)

    # --- taps --------------------------------------------------------------------------

    def sync_taps(self) -> None:
        here = self.hub.robots()
        for name in list(self.robots):
            if name not in here:
                for tap in self.robots.pop(name).taps:
                    tap.close()
        for name in here - self.robots.keys():
            robot = self.robots[name] = _Robot(name)
            robot.taps = [
                self.hub.tap(f"/{name}/pose", self._on_pose(robot)),
                self.hub.tap(f"/{name}/scan", self._on_scan(robot)),
            ]

    def _on_pose(self, robot: _Robot) -> OnMessage:
        def on_pose(_topic: Topic, msg: dict[str, Any]) -> None:
            found = pose_of(msg)
            if found is not None and found.map_id and math.isfinite(found.x + found.y + found.yaw):
                robot.pose = (found.map_id, (found.x, found.y, found.yaw))

        return on_pose

    def _on_scan(self, robot: _Robot) -> OnMessage:
        def on_scan(_topic: Topic, msg: dict[str, Any]) -> None:
            if robot.pose is None or not _moved(robot.taken, robot.pose):
                return
            robot.taken = robot.pose
            if len(self.queue) == self.queue.maxlen:
                self.dropped += 1
            self.queue.append((robot.name, robot.pose[0], robot.pose[1], msg))

        return on_scan

    # --- the worker thread -------------------------------------------------------------

    def process(
        self, batch: Sequence[tuple[str, str, tuple[float, float, float], dict[str, Any]]]
    ) -> None:
        now = time.monotonic()
        for robot, map_id, pose, msg in batch:
            left = self._where.get(robot)
            if left is not None and left != map_id and left in self.maps:
                self.maps[left].evidence.end_pass()  # the robot left that sub-map
            self._where[robot] = map_id
            held = self._evidence(map_id, now)
            if held is None:
                continue
            try:
                scan = Scan.from_message(msg)
            except ValueError:
                continue
            held.evidence.add(pose, scan)
            if now - held.pass_started >= PASS_SECONDS:
                held.evidence.end_pass()
                held.pass_started = now

    def _evidence(self, map_id: str, now: float) -> _MapEvidence | None:
        held = self.maps.get(map_id)
        if held is not None:
            return held
        building, _, code = map_id.partition("/")
        submap = SubMap.objects.filter(building__code=building, code=code).first()
        if submap is None:
            return None
        grid = services.grid_of(submap)
        evidence = Evidence(grid, (submap.origin_x, submap.origin_y), submap.resolution)
        held = self.maps[map_id] = _MapEvidence(submap.pk, submap.revision, evidence, now)
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


def _moved(
    before: tuple[str, tuple[float, float, float]] | None,
    now: tuple[str, tuple[float, float, float]],
) -> bool:
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
            "passes": proposal.passes,
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
    otherwise. Raises MappingError for a proposal no longer open."""
    locked = ChangeProposal.objects.select_for_update().get(pk=proposal.pk)
    if locked.state != ChangeProposal.OPEN:
        raise MappingError(f"This proposal is {locked.state}.")
    locked.added_passes = _passes_of(added, locked.added, locked.added_passes)
    locked.removed_passes = _passes_of(removed, locked.removed, locked.removed_passes)
    locked.added, locked.removed, locked.unknown = added, removed, unknown
    locked.edited = True
    locked.save()
    return locked


def _passes_of(cells: list[list[int]], proposed: list[list[int]], passes: list[int]) -> list[int]:
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
