"""The event log of one server process: derives events in memory (``EventDeriver``) as the
hub relays robots' messages and writes them in batches off the relay's path.

The hub calls ``connected``, ``disconnected``, ``heard``, ``observe`` and ``teleop``: each
touches only memory. ``run`` ticks the deriver (silent and stuck robots) and writes what
was derived every ``interval`` seconds, one ``bulk_create`` per batch; it runs while a
robot is watched or events wait, and is restarted by the next observation.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import time
import uuid
from collections.abc import Callable, Iterable, Mapping
from dataclasses import replace
from datetime import UTC, datetime
from typing import Any

from channels.db import database_sync_to_async
from django.db import transaction
from django.db.models import Max

from cloudnav_core import topics
from cloudnav_core.messages import WaitOrder, published_pose_of
from cloudnav_django.batches import UNREACHABLE, BatchInterrupted, write_batch
from cloudnav_django.outage import REPORT
from maps.models import Building
from robots.models import Robot
from telemetry.domain.events import EventDeriver, EventDraft, Kind, Severity
from telemetry.domain.storable import storable, storable_text

from .models import Event

logger = logging.getLogger(__name__)

# This process, as the ``origin`` of the events its event log writes.
ORIGIN = uuid.uuid4().hex[:12]
# The longest message an event keeps (``Event.message``).
MESSAGE_MAX = Event._meta.get_field("message").max_length or 500
# Events read from the log at most at once by a recorder.
FOREIGN_BATCH = 1000

# Topic kinds (relative to a robot's namespace) whose messages events are derived from.
OBSERVED = (topics.POSE, topics.NAV_STATUS, topics.LOCALISATION, topics.BATTERY)


class EventLog:
    """Events of the robots connected to this process, written in the background."""

    def __init__(
        self,
        interval: float = 1.0,
        clock: Callable[[], float] = time.time,
        deriver: EventDeriver | None = None,
    ) -> None:
        self.interval = interval
        self.clock = clock
        self.deriver = deriver or EventDeriver()
        self._pending: list[EventDraft] = []
        self._task: asyncio.Task[None] | None = None
        # Called on the loop with each event as it is derived (the recorder's queue); it
        # must return at once and never raise.
        self.on_event: Callable[[EventDraft], None] | None = None
        # Called on the loop with each stuck alert raised here (the fleet's stuck rule).
        self.on_stuck: Callable[[EventDraft], None] | None = None

    def connected(self, robot: str) -> None:
        self._add(self.deriver.connected(robot, self.clock()))

    def disconnected(self, robot: str) -> None:
        self._add(self.deriver.disconnected(robot, self.clock()))

    def heard(self, robot: str) -> None:
        self.deriver.heard(robot, self.clock())

    def observe(self, robot: str, kind: str, msg: Mapping[str, Any]) -> None:
        """A message on one of ``robot``'s OBSERVED topics."""
        now = self.clock()
        if kind == topics.POSE:
            pose = published_pose_of(msg)
            if pose is not None:
                self.deriver.pose(robot, pose.map_id, pose.x, pose.y, now)
        elif kind == topics.NAV_STATUS:
            self._add(self.deriver.nav_status(robot, msg, now))
        elif kind == topics.LOCALISATION:
            self._add(self.deriver.localisation(robot, msg, now))
        elif kind == topics.BATTERY:
            self._add(self.deriver.battery(robot, msg, now))

    def goal_sent(self, robot: str, actor: str, msg: Mapping[str, Any], note: str = "") -> None:
        """``actor`` (a label) published ``msg`` on ``robot``'s goal topic; ``note`` says
        what the server did to it (moved it off another robot's spot)."""
        self._add(self.deriver.goal_sent(robot, actor, msg, self.clock(), note))

    def waypoint_timed_out(self, robot: str, waypoint: Mapping[str, Any], then: str) -> None:
        """``robot`` did not reach its mission's ``waypoint`` in time; ``then`` says what
        followed (``EventDeriver.waypoint_timed_out``)."""
        self._add(self.deriver.waypoint_timed_out(robot, waypoint, then, self.clock()))

    def right_of_way(self, robot: str, text: str, order: WaitOrder | None) -> None:
        """The arbiter told ``robot`` to wait (``order``) or to go on; ``text`` says so."""
        data: dict[str, Any] = {"state": "go"}
        if order is not None:
            data = {
                "state": "wait",
                "map_id": order.map_id,
                "x": order.spot[0],
                "y": order.spot[1],
                "place": list(order.place),
                "waiting_for": order.waiting_for,
            }
        self._add(self.deriver.server_said(robot, Kind.RIGHT_OF_WAY, text, self.clock(), **data))

    def fleet_rule(self, robot: str, text: str, action: str, severity: Severity) -> None:
        """What the fleet rule did with a stuck robot (``action``: wait, replan, abort)."""
        drafts = self.deriver.server_said(
            robot, Kind.FLEET_RULE, text, self.clock(), severity, action=action
        )
        self._add(drafts)

    def stopped(self, robot: str, actor: str, done: Mapping[str, Any]) -> None:
        """``actor`` (a label) stopped ``robot``; ``done`` says how."""
        self._add(self.deriver.stopped(robot, actor, done, self.clock()))

    def teleop(self, robot: str, kind: Kind, holder: str) -> None:
        self._add(self.deriver.teleop(robot, kind, holder, self.clock()))

    def _add(self, drafts: list[EventDraft]) -> None:
        self._derived(drafts)
        if self._task is None or self._task.done():
            self._task = asyncio.get_running_loop().create_task(self.run())

    async def run(self) -> None:
        """Tick and write until nothing is watched and nothing waits."""
        while True:
            await asyncio.sleep(self.interval)
            self._derived(self.deriver.tick(self.clock()))
            await self.flush()
            if not self._pending and not self.deriver.watching():
                return

    def _derived(self, drafts: list[EventDraft]) -> None:
        drafts = [storable_draft(d) for d in drafts]
        self._pending.extend(drafts)
        if self.on_stuck is not None:
            for draft in drafts:
                if draft.kind is Kind.STUCK:
                    self.on_stuck(draft)
        if self.on_event is not None:
            for draft in drafts:
                if draft.kind is not Kind.ALERT_CLEARED:
                    self.on_event(draft)

    async def flush(self) -> None:
        batch, self._pending = self._pending, []
        if not batch:
            return
        try:
            stored = await database_sync_to_async(store_events)(batch, ORIGIN)
        except BatchInterrupted as interrupted:
            unwritten = interrupted.unwritten
            REPORT.failed("event batches held back", interrupted)
            self._pending[:0] = unwritten
            return
        except Exception:  # never retried: a batch that cannot be written must not block
            logger.exception("%d events could not be written and are dropped", len(batch))
            return
        # A clearing is news only where it cleared an alert: told once it is known.
        for draft, _ in stored:
            if draft.kind is Kind.ALERT_CLEARED and self.on_event is not None:
                self.on_event(draft)

    async def close(self) -> None:
        """Write what waits (a process shutting down)."""
        if self._task is not None:
            self._task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await self._task
        await self.flush()


def write_events(batch: list[EventDraft], origin: str = "") -> list[Event]:
    """Store ``batch`` (see ``store_events``) and return the rows written."""
    return [row for _, row in store_events(batch, origin)]


def store_events(batch: list[EventDraft], origin: str = "") -> list[tuple[EventDraft, Event]]:
    """Store ``batch``: two lookups (robots with their buildings, buildings by code), one
    of the open alerts of its robots when it raises or clears any, one insert (row by row
    if the database refuses it: a refused event is logged and dropped, never retried), and
    one update per draft that clears alerts. An event's building is the one its robot was
    last seen in, else the robot's first building. ``origin`` is the process whose event
    log derived them ("" for a request's own events).

    One condition, one alert: an alert whose robot has one of its kind not cleared yet is
    not stored. A draft's ``clears`` closes the robot's open alerts of those kinds
    (``cleared_at`` = its time); an ``alert_cleared`` draft that closed none is not
    stored. Returns each stored draft with its row. Raises ``BatchInterrupted`` holding
    the drafts not written when the database cannot be reached."""
    try:
        kept, alerts = _kept(batch, origin)
    except UNREACHABLE as error:
        raise BatchInterrupted(batch) from error
    written: list[Event] = []
    rows = [row for _, row in kept]
    try:
        write_batch(rows, lambda some: written.extend(Event.objects.bulk_create(some)), "an event")
    except BatchInterrupted as interrupted:  # rows and drafts in the same order
        left = [draft for draft, _ in kept[len(kept) - len(interrupted.unwritten) :]]
        raise BatchInterrupted(left) from interrupted
    alerts.close()
    stored = {id(row) for row in written}
    return [(draft, row) for draft, row in kept if id(row) in stored]


def _kept(
    batch: list[EventDraft], origin: str
) -> tuple[list[tuple[EventDraft, Event]], _OpenAlerts]:
    """The drafts of ``batch`` to store, with their rows, and the open alerts they close."""
    robots = {
        r.name: r
        for r in Robot.objects.filter(
            name__in={d.robot for d in batch if d.robot}
        ).prefetch_related("buildings")
    }
    codes = {d.building for d in batch if d.building}
    buildings = {b.code: b for b in Building.objects.filter(code__in=codes)}
    alerts = _OpenAlerts(batch, robots.values())
    kept: list[tuple[EventDraft, Event]] = []
    for draft in batch:
        robot = robots.get(draft.robot or "")
        building = buildings.get(draft.building or "")
        if building is None and robot is not None:
            building = next(iter(robot.buildings.all()), None)
        row = _row(draft, robot, building, origin)
        if alerts.keep(draft, row):
            kept.append((draft, row))
    return kept, alerts


def _row(draft: EventDraft, robot: Robot | None, building: Building | None, origin: str) -> Event:
    return Event(
        time=datetime.fromtimestamp(draft.time, UTC),
        building=building,
        robot=robot,
        kind=draft.kind.value,
        severity=draft.severity.value,
        actor=draft.actor,
        message=draft.message[:MESSAGE_MAX],
        data=dict(draft.data),
        alert=draft.alert,
        origin=origin,
    )


def storable_draft(draft: EventDraft) -> EventDraft:
    """``draft`` with its text as the event log stores it (``storable``): a robot's text
    with a NUL in it is an event like any other, never a batch the database refuses."""
    return replace(
        draft,
        message=storable_text(draft.message),
        actor=storable_text(draft.actor),
        data=storable(dict(draft.data)),
    )


class _OpenAlerts:
    """The alerts of a batch's robots not cleared yet, by robot and kind: stored ones read
    at once, and the batch's own as they are kept."""

    def __init__(self, batch: list[EventDraft], robots: Iterable[Robot]) -> None:
        self._open: dict[tuple[int, str], list[Event]] = {}
        self._closing: list[tuple[datetime, list[int]]] = []
        if any(d.alert or d.clears for d in batch):
            rows = Event.objects.filter(
                robot__in=[r.pk for r in robots], alert=True, cleared_at__isnull=True
            ).only("id", "robot_id", "kind")
            for row in rows:
                self._open.setdefault((row.robot_id, row.kind), []).append(row)  # type: ignore[arg-type]

    def keep(self, draft: EventDraft, row: Event) -> bool:
        """Whether ``row`` (``draft`` as a row) is to be stored; closes what it clears."""
        if row.robot_id is None:
            return draft.kind is not Kind.ALERT_CLEARED
        closed = [self._close(row.robot_id, kind, row.time) for kind in draft.clears]
        if draft.alert:
            if self._open.get((row.robot_id, row.kind)):
                return False
            self._open[(row.robot_id, row.kind)] = [row]
        return draft.kind is not Kind.ALERT_CLEARED or any(closed)

    def _close(self, robot_id: int, kind: Kind, when: datetime) -> bool:
        rows = self._open.pop((robot_id, kind.value), [])
        for row in rows:
            row.cleared_at = when  # the batch's own, not stored yet
        self._closing.append((when, [row.pk for row in rows if row.pk is not None]))
        return bool(rows)

    def close(self) -> None:
        """Write the clearing of alerts stored before this batch."""
        for when, ids in self._closing:
            if ids:
                Event.objects.filter(pk__in=ids, cleared_at__isnull=True).update(cleared_at=when)


def write_on_commit(draft: EventDraft) -> None:
    """Store ``draft`` (an event a request derived) once its transaction commits."""
    transaction.on_commit(lambda: write_events([storable_draft(draft)]))


def foreign_events(after: int | None, robots: frozenset[str]) -> tuple[int, list[EventDraft]]:
    """The events ``robots`` are concerned in that the log holds after event id ``after``
    and this process's event log did not derive (other server processes', requests'), as
    ``(last id read, drafts)``, each draft naming its robot (a building's event, such as a
    new map version, once per robot of that building). ``after`` None starts at the end."""
    if after is None:
        return Event.objects.aggregate(last=Max("id"))["last"] or 0, []
    rows = list(
        Event.objects.filter(id__gt=after)
        .exclude(origin=ORIGIN)
        .select_related("robot", "building")
        .order_by("id")[:FOREIGN_BATCH]
    )
    drafts = []
    for row in rows:
        for robot in _concerned(row, robots):
            drafts.append(_draft_of(row, robot))
    return (rows[-1].id if rows else after), drafts


def _concerned(row: Event, robots: frozenset[str]) -> list[str]:
    if row.robot is not None:
        return [row.robot.name] if row.robot.name in robots else []
    if row.building_id is None or not robots:
        return []
    members = Robot.objects.filter(buildings=row.building_id, name__in=robots)
    return sorted(members.values_list("name", flat=True))


def _draft_of(row: Event, robot: str) -> EventDraft:
    return EventDraft(
        time=row.time.timestamp(),
        kind=Kind(row.kind),
        severity=Severity(row.severity),
        robot=robot,
        message=row.message,
        actor=row.actor,
        building=row.building.code if row.building is not None else None,
        data=row.data,
    )
