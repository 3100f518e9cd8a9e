"""Fleet state: each connected robot's last pose, Map ID (and the version of it held) and
last-seen time, kept in memory
and written to ``RobotState`` by a background flush, never once per message.

The rosbridge server calls ``connected``, ``pose``, ``map_id`` and ``disconnected``; these
only touch a dict. ``run`` writes what changed every ``interval`` seconds (and at once for
a change of online state), and refreshes ``last_seen`` of the robots still connected, so a
server that died leaves them looking stale, not online.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from datetime import UTC, datetime, timedelta
from functools import partial

from channels.db import database_sync_to_async

from cloudnav_core.messages import Pose2D
from cloudnav_django.batches import UNREACHABLE, BatchInterrupted, write_batch
from cloudnav_django.outage import REPORT
from maps.domain.versions import split_map_ref
from robots.models import RobotState

logger = logging.getLogger(__name__)


NEVER = datetime.min.replace(tzinfo=UTC)


@dataclass
class _Entry:
    online: bool = True
    pose: Pose2D | None = None
    map_id: str | None = None
    map_version: int | None = None  # the version of ``map_id`` the robot said it holds
    last_seen: datetime = field(default_factory=lambda: datetime.now(UTC))
    connections: int = 0
    written: datetime = field(default=NEVER)


class FleetTracker:
    """The fleet state of the robots connected to this process, flushed in the background."""

    def __init__(self, interval: float = 1.0) -> None:
        self.interval = interval
        self._entries: dict[int, _Entry] = {}
        self._dirty: set[int] = set()
        self._urgent = asyncio.Event()
        self._task: asyncio.Task[None] | None = None

    def _entry(self, robot_pk: int) -> _Entry:
        entry = self._entries.get(robot_pk)
        if entry is None:
            entry = self._entries[robot_pk] = _Entry()
        return entry

    def connected(self, robot_pk: int) -> None:
        entry = self._entry(robot_pk)
        entry.connections += 1
        entry.online = True
        self._touch(robot_pk, entry, urgent=True)

    def disconnected(self, robot_pk: int) -> None:
        entry = self._entry(robot_pk)
        entry.connections = max(0, entry.connections - 1)
        if entry.connections == 0:
            entry.online = False
            self._touch(robot_pk, entry, urgent=True)

    def forget(self, robot_pk: int) -> None:
        """Drop a deleted robot's state: it has no row to write any more."""
        self._entries.pop(robot_pk, None)
        self._dirty.discard(robot_pk)

    def pose(self, robot_pk: int, pose: Pose2D) -> None:
        """Keep a pose; one with a coordinate that is not finite is ignored, and a frame
        that is no storable Map ID keeps the pose without it (``valid_pose``)."""
        if not valid_pose(pose):
            return
        entry = self._entry(robot_pk)
        entry.pose = pose
        if pose.map_id and valid_map_id(pose.map_id) and pose.map_id != entry.map_id:
            entry.map_id, entry.map_version = pose.map_id, None
        self._touch(robot_pk, entry)

    def map_id(self, robot_pk: int, name: str) -> None:
        """The robot's ``map_id`` message: a Map ID, with the version held
        (``building/code@v<n>``) when the robot says it; one whose Map ID cannot be
        stored (``valid_map_id``) is ignored."""
        if not valid_map_id(split_map_ref(name)[0]):
            return
        entry = self._entry(robot_pk)
        entry.map_id, entry.map_version = split_map_ref(name)
        self._touch(robot_pk, entry)

    def _touch(self, robot_pk: int, entry: _Entry, urgent: bool = False) -> None:
        entry.last_seen = datetime.now(UTC)
        self._dirty.add(robot_pk)
        if urgent:
            self._urgent.set()
        self._ensure_running()

    def _ensure_running(self) -> None:
        if self._task is None or self._task.done():
            self._task = asyncio.get_running_loop().create_task(self.run())

    async def run(self) -> None:
        """Flush until nothing is connected; restarted by the next change."""
        while True:
            with contextlib.suppress(TimeoutError):
                await asyncio.wait_for(self._urgent.wait(), self.interval)
            self._urgent.clear()
            await self.flush()
            if not self._entries:
                return

    async def flush(self) -> None:
        """Write every changed robot's state, and a heartbeat for the quiet connected ones."""
        now = datetime.now(UTC)
        for pk, entry in self._entries.items():
            if entry.online and now - entry.written > HEARTBEAT:
                entry.last_seen = now
                self._dirty.add(pk)
        batch = {pk: self._entries[pk] for pk in self._dirty if pk in self._entries}
        self._dirty.clear()
        for pk in [pk for pk, e in batch.items() if not e.online]:
            del self._entries[pk]
        if batch:
            try:
                failed = await database_sync_to_async(write_states)(batch)
            except Exception as error:
                if isinstance(error, (*UNREACHABLE, BatchInterrupted)):
                    REPORT.failed("fleet state flushes held back", error)
                else:
                    logger.exception("fleet state flush failed; retrying with the next one")
                self._dirty.update(batch)
                return
            for pk, entry in batch.items():
                if pk not in failed:
                    entry.written = now
            # a row that failed alone is not retried at once: its robot's next change (or
            # heartbeat) writes it again, and it never holds back the others meanwhile


def valid_pose(pose: Pose2D) -> bool:
    """True if every coordinate of ``pose`` is finite (NaN and infinity are not stored,
    and cannot be written as JSON)."""
    return all(math.isfinite(v) for v in (pose.x, pose.y, pose.yaw))


MAP_ID_MAX = RobotState._meta.get_field("map_id").max_length or 100


def valid_map_id(map_id: str) -> bool:
    """True if ``map_id`` fits ``RobotState.map_id``: at most ``MAP_ID_MAX`` characters,
    none of them a control character (PostgreSQL refuses NUL in text)."""
    return len(map_id) <= MAP_ID_MAX and map_id.isprintable()


def write_states(batch: dict[int, _Entry]) -> set[int]:
    """Upsert the rows of ``batch`` and return the robots whose row could not be written.

    One query per combination of known fields, row by row where the database refuses one
    (``write_batch``: a robot deleted meanwhile, a row the database refuses), so one bad
    row never blocks the others. Raises ``BatchInterrupted`` when the database cannot be
    reached."""
    failed: set[int] = set()
    for rows, known in _groups(batch):
        refused = write_batch(rows, partial(_upsert, known=known), "a robot's fleet state")
        failed.update(row.robot_id for row in refused)
    return failed


def _upsert(rows: Sequence[RobotState], known: tuple[str, ...]) -> None:
    RobotState.objects.bulk_create(
        rows, update_conflicts=True, unique_fields=["robot"], update_fields=list(known)
    )


def _groups(batch: dict[int, _Entry]) -> list[tuple[list[RobotState], tuple[str, ...]]]:
    """The rows of ``batch`` grouped by the fields they know."""
    groups: dict[tuple[str, ...], list[RobotState]] = {}
    for pk, entry in batch.items():
        fields: list[str] = ["online", "last_seen"]
        row = RobotState(robot_id=pk, online=entry.online, last_seen=entry.last_seen)
        if entry.map_id is not None:
            row.map_id, row.map_version = entry.map_id, entry.map_version
            fields += ["map_id", "map_version"]
        if entry.pose is not None:
            row.x, row.y, row.yaw = entry.pose.x, entry.pose.y, entry.pose.yaw
            fields += ["x", "y", "yaw"]
        groups.setdefault(tuple(fields), []).append(row)
    return [(rows, known) for known, rows in groups.items()]


# Connected robots are written at least this often, even when nothing changed, so a
# robot whose row is older than ``robots.models.STALE_AFTER`` is shown offline.
HEARTBEAT = timedelta(seconds=10)
