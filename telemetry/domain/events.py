"""What happened to the fleet, derived in memory from what robots publish and the server does.

An ``EventDraft`` is one occurrence: when, which robot, what kind, how severe, who caused it
(``actor``: ``server``, ``robot:<name>``, ``user:<name>``), a sentence for people and the
data behind it. The same record is what the database keeps (``telemetry.models.Event``) and
what a recording will carry, so its fields are plain values. Some kinds are alerts: they
stay open until someone acknowledges them or their condition ends. A draft's ``clears``
names the alerts whose condition it ends (the robot is back, localised, charged, moving);
an ``alert_cleared`` draft exists only for that, and is kept only where it cleared one.
The event log keeps one open alert per robot and condition: the same condition never
raises twice.

``EventDeriver`` turns observations into drafts. It is called on the relay's hot path
(each pose, each status), so every observation is a few dictionary operations and no I/O;
``tick`` finds what only the passing of time reveals (a silent robot, a stuck one).

Silence is measured on the server's clock (it is the network's fact). A lack of progress
is measured on both clocks, the robot's own where ``clocks`` knows it
(``cloudnav_core.times.RobotClocks``, read from its stamps) and the server's, and counts
as the shorter: a simulation at a quarter of real time is stuck after ``stuck_after`` of
its own seconds, not a quarter of them; one eight times faster than real time is not
stuck after an eighth of them, on waits (a bundle's download, a server's answer) that run
on the server's clock.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, replace
from enum import StrEnum
from typing import Any

from cloudnav_core.times import RobotClocks


class Kind(StrEnum):
    CONNECTED = "robot_connected"
    DISCONNECTED = "robot_disconnected"
    SILENT = "robot_silent"
    GOAL_ABORTED = "goal_aborted"
    STUCK = "robot_stuck"
    LOST = "robot_lost"
    DEADMAN_STOP = "deadman_stop"
    TELEOP_LAPSED = "teleop_lapsed"
    BATTERY_LOW = "battery_low"
    GOAL_SENT = "goal_sent"
    GOAL_REACHED = "goal_reached"
    GOAL_CANCELLED = "goal_cancelled"
    TELEOP_TAKEN = "teleop_taken"
    TELEOP_RELEASED = "teleop_released"
    TAG_READ = "tag_read"
    RELOCALISED = "relocalised"
    BUNDLE_FETCHED = "bundle_fetched"
    MAP_VERSION_CHANGED = "map_version_changed"
    ROBOT_STOPPED = "robot_stopped"
    WAYPOINT_TIMED_OUT = "waypoint_timed_out"
    RIGHT_OF_WAY = "right_of_way"
    FLEET_RULE = "fleet_rule"
    ALERT_CLEARED = "alert_cleared"


class Severity(StrEnum):
    INFO = "info"
    WARNING = "warning"
    ERROR = "error"


# Kinds someone must acknowledge.
ALERTS = frozenset(
    {
        Kind.DISCONNECTED,
        Kind.SILENT,
        Kind.GOAL_ABORTED,
        Kind.STUCK,
        Kind.LOST,
        Kind.BATTERY_LOW,
    }
)
# A connected robot that published nothing for this long has gone silent.
SILENT_AFTER_S = 5.0
# A robot with an active goal that moved less than STUCK_METRES in STUCK_AFTER_S is stuck
# (the default of ``CLOUDNAV_STUCK_AFTER``).
STUCK_AFTER_S = 30.0
STUCK_METRES = 0.25
# A robot that says it is lost before it was ever localised since it connected is still
# starting (about to read its first tag): an alert only once it has been so this long.
STARTING_GRACE_S = 60.0
# Battery fraction under which an alert is raised, and over which it may be raised again.
BATTERY_LOW = 0.2
BATTERY_RECOVERED = 0.3
# actionlib_msgs/GoalStatus codes.
_ACTIVE = 1
_FAILED = {4: "aborted", 5: "rejected", 9: "lost"}
_ENDED = {
    3: (Kind.GOAL_REACHED, "reached"),
    2: (Kind.GOAL_CANCELLED, "cancelled"),
    8: (Kind.GOAL_CANCELLED, "cancelled"),
}


@dataclass(frozen=True)
class EventDraft:
    """One event, before it is stored: ``time`` in seconds since the epoch."""

    time: float
    kind: Kind
    severity: Severity
    robot: str | None
    message: str
    actor: str = "server"
    building: str | None = None
    data: Mapping[str, Any] = field(default_factory=dict)
    clears: frozenset[Kind] = frozenset()

    @property
    def alert(self) -> bool:
        return self.kind in ALERTS


@dataclass
class _Watch:
    """What the deriver remembers of one robot."""

    building: str | None = None
    connected: bool = False
    heard: float = 0.0
    silent: bool = False
    status_key: tuple[str, int] | None = None
    goal_active: bool = False
    anchor: tuple[float, float, float] | None = None  # x, y, time of the last real move
    on_robot_clock: bool = False  # the anchor's and moved_at's times are the robot's
    anchor_wall: float = 0.0  # the server's time of the anchor
    stuck: bool = False
    localisation: str = ""
    placed: tuple[str, str] = ("", "")  # the map and source of the last localised state
    battery_low: bool = False
    at: tuple[float, float] | None = None
    connected_at: float = 0.0
    localised_once: bool = False  # since it connected; before that it is starting
    starting_overdue: bool = False
    stuck_since: float = 0.0  # the anchor time the stuck alert was raised at
    moved_at: float = -math.inf  # when it last moved STUCK_METRES from where it was
    # Alerts that may be open for this robot: those raised here, and after it connects
    # any from before (another process, an earlier run), which the log clears if open.
    raised: set[Kind] = field(default_factory=set)


Blocker = Callable[[str], "tuple[str, str] | None"]
"""What stands in a robot's way, if the fleet knows: (its name, a phrase such as ``robot_1
standing 0.6 m away``), or None."""


class EventDeriver:
    """Observations in, ``EventDraft`` lists out; keeps only the last state of each robot.

    A robot is stuck after ``stuck_after`` seconds without progress; ``blocker`` names what
    blocks it (another robot near it), else the alert says an unknown obstacle or person.
    """

    def __init__(
        self,
        stuck_after: float = STUCK_AFTER_S,
        blocker: Blocker | None = None,
        clocks: RobotClocks | None = None,
    ) -> None:
        self._watches: dict[str, _Watch] = {}
        self.stuck_after = stuck_after
        self.blocker = blocker
        self.clocks = clocks

    def _progress_time(self, robot: str, now: float) -> tuple[float, bool]:
        """The time progress is measured on for ``robot``: its own clock's where known
        (and True), else the server's ``now``."""
        robot_now = self.clocks.now(robot) if self.clocks is not None else None
        return (now, False) if robot_now is None else (robot_now, True)

    def _watch(self, robot: str, now: float) -> _Watch:
        watch = self._watches.get(robot)
        if watch is None:
            watch = self._watches[robot] = _Watch()
        watch.heard = now
        return watch

    def _draft(
        self,
        watch: _Watch,
        now: float,
        kind: Kind,
        severity: Severity,
        robot: str,
        message: str,
        **data: Any,
    ) -> EventDraft:
        if kind in ALERTS:
            watch.raised.add(kind)
        return EventDraft(
            now, kind, severity, robot, message, f"robot:{robot}", watch.building, data
        )

    def _clear(
        self, watch: _Watch, now: float, kind: Kind, robot: str, message: str
    ) -> list[EventDraft]:
        """An ``alert_cleared`` draft ending ``kind``, if such an alert may be open."""
        if kind not in watch.raised:
            return []
        watch.raised.discard(kind)
        draft = self._draft(watch, now, Kind.ALERT_CLEARED, Severity.INFO, robot, message)
        return [replace(draft, data={"alert": kind.value}, clears=frozenset({kind}))]

    def watching(self) -> bool:
        """True while a robot is watched (``tick`` has something to look at)."""
        return bool(self._watches)

    def connected(self, robot: str, now: float) -> list[EventDraft]:
        """News that clears the robot's disconnection and silence; from now on it is
        starting until it is first localised."""
        watch = self._watch(robot, now)
        watch.connected, watch.silent = True, False
        watch.connected_at, watch.localised_once, watch.starting_overdue = now, False, False
        watch.raised = set(ALERTS) - {Kind.DISCONNECTED, Kind.SILENT}
        draft = self._draft(watch, now, Kind.CONNECTED, Severity.INFO, robot, f"{robot} connected")
        return [replace(draft, clears=frozenset({Kind.DISCONNECTED, Kind.SILENT}))]

    def disconnected(self, robot: str, now: float) -> list[EventDraft]:
        watch = self._watch(robot, now)
        watch.connected = False
        watch.goal_active = False
        return [
            self._draft(
                watch, now, Kind.DISCONNECTED, Severity.WARNING, robot, f"{robot} disconnected"
            )
        ]

    def pose(self, robot: str, map_id: str, x: float, y: float, now: float) -> list[EventDraft]:
        watch = self._watch(robot, now)
        if "/" in map_id:
            watch.building = map_id.split("/", 1)[0]
        watch.at = (x, y)
        at, on_robot_clock = self._progress_time(robot, now)
        anchor = watch.anchor
        if anchor is None or on_robot_clock != watch.on_robot_clock or at < anchor[2]:
            # First pose, or a clock first heard or set back: progress is counted afresh
            # (and a stuck spell counted on the old clock ends at the next tick).
            watch.anchor, watch.on_robot_clock = (x, y, at), on_robot_clock
            watch.moved_at = watch.stuck_since = -math.inf
            watch.anchor_wall = now
        elif math.hypot(x - anchor[0], y - anchor[1]) >= STUCK_METRES:
            watch.anchor, watch.moved_at, watch.anchor_wall = (x, y, at), at, now
        return []

    def heard(self, robot: str, now: float) -> None:
        self._watch(robot, now)

    def moved_within(self, robot: str, seconds: float, now: float) -> bool:
        """True if ``robot`` moved STUCK_METRES or more in the last ``seconds`` (of its clock)."""
        watch = self._watches.get(robot)
        return watch is not None and self._progress_time(robot, now)[0] - watch.moved_at <= seconds

    def stuck_since(self, robot: str) -> float | None:
        """When ``robot``'s current stuck spell began (its last real move), None when it
        is not stuck."""
        watch = self._watches.get(robot)
        return watch.stuck_since if watch is not None and watch.stuck else None

    def stuck_for(self, robot: str, now: float) -> float:
        """Seconds since ``robot``'s current stuck spell began (its last real move; the
        shorter count of its clock's and the server's), 0 when it is not stuck."""
        watch = self._watches.get(robot)
        if watch is None or not watch.stuck:
            return 0.0
        return self._still_for(watch, robot, now)

    def _still_for(self, watch: _Watch, robot: str, now: float) -> float:
        """Seconds since the anchor (the last real move), the shorter count of the robot's
        clock's and the server's (see the module); 0 when none."""
        anchor = watch.anchor
        at, on_robot_clock = self._progress_time(robot, now)
        if anchor is None or on_robot_clock != watch.on_robot_clock:
            return 0.0
        return max(0.0, min(at - anchor[2], now - watch.anchor_wall))

    def nav_status(self, robot: str, msg: Mapping[str, Any], now: float) -> list[EventDraft]:
        """A GoalStatusArray: an aborted, rejected or lost goal once, with its reason."""
        watch = self._watch(robot, now)
        statuses = msg.get("status_list") or []
        latest = statuses[-1] if statuses else None
        if not isinstance(latest, Mapping):
            watch.goal_active = False
            return []
        code = int(latest.get("status") or 0)
        goal_id = str((latest.get("goal_id") or {}).get("id", ""))
        was_active, watch.goal_active = watch.goal_active, code == _ACTIVE
        if watch.goal_active and not was_active and watch.at is not None:
            watch.anchor = (*watch.at, now)
        key = (goal_id, code)
        if key == watch.status_key or (code not in _FAILED and code not in _ENDED):
            new_goal = watch.goal_active and key != watch.status_key
            watch.status_key = key
            if not new_goal:
                return []
            return self._clear(watch, now, Kind.GOAL_ABORTED, robot, f"{robot} took a new goal")
        watch.status_key = key
        if code in _ENDED:
            kind, verb = _ENDED[code]
            text = f"{robot}: goal {verb}"
            return [self._draft(watch, now, kind, Severity.INFO, robot, text, goal=goal_id)]
        reason = str(latest.get("text") or "no reason given")
        failed = self._draft(
            watch,
            now,
            Kind.GOAL_ABORTED,
            Severity.ERROR,
            robot,
            f"{robot}: goal {_FAILED[code]}: {reason}",
            goal=goal_id,
            status=_FAILED[code],
            reason=reason,
        )
        # the condition is "the robot's last goal failed": this failure replaces the last
        return [replace(failed, clears=frozenset({Kind.GOAL_ABORTED}))]

    def localisation(self, robot: str, msg: Mapping[str, Any], now: float) -> list[EventDraft]:
        """A DiagnosticStatus whose ``state`` value says lost, entering (a tag was read) or
        localised (``map_id`` by ``source``): lost once, a tag read once per entering, and
        relocalised when localised after being lost or by something other than a tag. Lost
        is an alert only once the robot was localised since it connected (before, it is
        starting: see ``tick``); being localised clears it."""
        watch = self._watch(robot, now)
        values = {
            v.get("key"): v.get("value") for v in msg.get("values") or [] if isinstance(v, Mapping)
        }
        state = str(values.get("state") or "")
        before, watch.localisation = watch.localisation, state
        map_id, source = str(values.get("map_id") or ""), str(values.get("source") or "")
        if state == "entering" and before != "entering":
            text = f"{robot} read {source or 'a tag'}: entering {map_id}"
            return [
                self._draft(
                    watch,
                    now,
                    Kind.TAG_READ,
                    Severity.INFO,
                    robot,
                    text,
                    map_id=map_id,
                    source=source,
                )
            ]
        if state == "localised":
            watch.localised_once = True
            found = self._localised(watch, robot, before, (map_id, source), now)
            return found + self._clear(watch, now, Kind.LOST, robot, f"{robot} is localised")
        if state != "lost" or before == "lost" or not watch.localised_once:
            return []
        return [
            self._draft(
                watch,
                now,
                Kind.LOST,
                Severity.WARNING,
                robot,
                f"{robot} is lost: {msg.get('message') or 'looking for a tag'}",
                detail=str(msg.get("message") or ""),
            )
        ]

    def _localised(
        self, watch: _Watch, robot: str, before: str, placed: tuple[str, str], now: float
    ) -> list[EventDraft]:
        previous, watch.placed = watch.placed, placed
        map_id, source = placed
        by_tag = source.startswith("tag ")
        if before == "":  # the robot's first word: where it starts, not a change
            return []
        if before != "lost" and (placed == previous or by_tag):
            return []
        text = f"{robot} relocalised in {map_id} by {source or 'an unnamed source'}"
        return [
            self._draft(
                watch,
                now,
                Kind.RELOCALISED,
                Severity.INFO,
                robot,
                text,
                map_id=map_id,
                source=source,
            )
        ]

    def goal_sent(
        self, robot: str, actor: str, msg: Mapping[str, Any], now: float, note: str = ""
    ) -> list[EventDraft]:
        """A ``geometry_msgs/PoseStamped`` sent to the robot's goal topic by ``actor``;
        ``note`` (if any) ends the sentence: what the server did to the goal."""
        watch = self._watches.get(robot) or _Watch()
        header = msg.get("header")
        map_id = str(header.get("frame_id") or "") if isinstance(header, Mapping) else ""
        pose = msg.get("pose")
        position = pose.get("position") if isinstance(pose, Mapping) else None
        x, y = (position.get("x"), position.get("y")) if isinstance(position, Mapping) else (0, 0)
        text = f"{actor} sent {robot} a goal in {map_id or 'its map'}"
        text += f": {note}" if note else ""
        return [
            EventDraft(
                now,
                Kind.GOAL_SENT,
                Severity.INFO,
                robot,
                text,
                actor,
                watch.building,
                {"map_id": map_id, "x": x, "y": y},
            )
        ]

    def stopped(
        self, robot: str, actor: str, done: Mapping[str, Any], now: float
    ) -> list[EventDraft]:
        """``actor`` pressed STOP for ``robot``; ``done`` says what the stop did (the goal
        cancelled, missions paused, whose teleop lock was withdrawn)."""
        watch = self._watches.get(robot) or _Watch()
        text = f"{robot} stopped by {actor}: {done.get('message', 'zero velocity sent')}"
        return [
            EventDraft(
                now, Kind.ROBOT_STOPPED, Severity.WARNING, robot, text, actor, watch.building, done
            )
        ]

    def server_said(
        self,
        robot: str,
        kind: Kind,
        text: str,
        now: float,
        severity: Severity = Severity.INFO,
        **data: Any,
    ) -> list[EventDraft]:
        """What the server decided for ``robot`` (who waits in a narrow place, what the
        fleet rule does with a stuck robot), said in ``text``."""
        watch = self._watches.get(robot) or _Watch()
        return [EventDraft(now, kind, severity, robot, text, "server", watch.building, data)]

    def waypoint_timed_out(
        self, robot: str, waypoint: Mapping[str, Any], then: str, now: float
    ) -> list[EventDraft]:
        """``robot`` did not reach its mission's ``waypoint`` (``map_id``, ``x``, ``y``,
        ``time_limit``) in time; ``then`` says what followed (skipped, or paused)."""
        watch = self._watches.get(robot) or _Watch()
        text = (
            f"{robot} did not reach its waypoint in {waypoint['map_id']} "
            f"({waypoint['x']:.2f}, {waypoint['y']:.2f}) within {waypoint['time_limit']:g} s: "
            f"{then}"
        )
        return [
            EventDraft(
                now,
                Kind.WAYPOINT_TIMED_OUT,
                Severity.WARNING,
                robot,
                text,
                "server",
                watch.building,
                {**waypoint, "then": then},
            )
        ]

    def battery(self, robot: str, msg: Mapping[str, Any], now: float) -> list[EventDraft]:
        """A BatteryState: an alert when ``percentage`` (0..1) falls under BATTERY_LOW."""
        watch = self._watch(robot, now)
        level = msg.get("percentage")
        if not isinstance(level, int | float) or not math.isfinite(level):
            return []
        if level >= BATTERY_RECOVERED:
            watch.battery_low = False
            text = f"{robot}: battery back at {round(level * 100)} %"
            return self._clear(watch, now, Kind.BATTERY_LOW, robot, text)
        if level >= BATTERY_LOW or watch.battery_low:
            return []
        watch.battery_low = True
        return [
            self._draft(
                watch,
                now,
                Kind.BATTERY_LOW,
                Severity.WARNING,
                robot,
                f"{robot}: battery at {round(level * 100)} %",
                percentage=float(level),
            )
        ]

    def teleop(self, robot: str, kind: Kind, holder: str, now: float) -> list[EventDraft]:
        """A teleop lock taken, released or lapsed, or a dead-man stop, by ``holder`` (its
        label)."""
        watch = self._watch(robot, now)
        text = {
            Kind.DEADMAN_STOP: f"{robot} stopped: no command from {holder} for half a second",
            Kind.TELEOP_LAPSED: f"{holder}'s teleop lock of {robot} lapsed",
            Kind.TELEOP_TAKEN: f"{holder} took the teleop lock of {robot}",
            Kind.TELEOP_RELEASED: f"{holder} released the teleop lock of {robot}",
        }[kind]
        severity = Severity.WARNING if kind is Kind.DEADMAN_STOP else Severity.INFO
        return [
            EventDraft(now, kind, severity, robot, text, holder, watch.building, {"holder": holder})
        ]

    def tick(self, now: float) -> list[EventDraft]:
        """Events only time reveals: robots gone silent or heard again, robots stuck on
        their way or moving again, robots that never localised after connecting."""
        drafts: list[EventDraft] = []
        for robot, watch in list(self._watches.items()):
            if not watch.connected:
                del self._watches[robot]
                continue
            drafts += self._silence(watch, robot, now)
            drafts += self._stuck(watch, robot, now)
            drafts += self._starting(watch, robot, now)
        return drafts

    def _silence(self, watch: _Watch, robot: str, now: float) -> list[EventDraft]:
        quiet = now - watch.heard
        if watch.silent and quiet <= SILENT_AFTER_S:
            watch.silent = False
            return self._clear(watch, now, Kind.SILENT, robot, f"{robot} is heard again")
        if watch.silent or quiet <= SILENT_AFTER_S:
            return []
        watch.silent = True
        text = f"{robot} has published nothing for {round(quiet)} s"
        return [
            self._draft(
                watch, now, Kind.SILENT, Severity.WARNING, robot, text, seconds=round(quiet, 1)
            )
        ]

    def _stuck(self, watch: _Watch, robot: str, now: float) -> list[EventDraft]:
        anchor = watch.anchor
        if watch.stuck and (not watch.goal_active or not anchor or anchor[2] > watch.stuck_since):
            watch.stuck = False
            text = f"{robot} is moving again" if watch.goal_active else f"{robot} has no goal"
            return self._clear(watch, now, Kind.STUCK, robot, text)
        if (
            watch.stuck
            or not watch.goal_active
            or not anchor
            or (still := self._still_for(watch, robot, now)) <= self.stuck_after
        ):
            return []
        watch.stuck, watch.stuck_since = True, anchor[2]
        found = self.blocker(robot) if self.blocker is not None else None
        blocker, why = found or ("unknown", "an unknown obstacle or person")
        text = (
            f"{robot} has a goal but moved less than {STUCK_METRES} m in "
            f"{round(still)} s: blocked by {why}"
        )
        return [
            self._draft(
                watch,
                now,
                Kind.STUCK,
                Severity.WARNING,
                robot,
                text,
                x=anchor[0],
                y=anchor[1],
                blocker=blocker,
            )
        ]

    def _starting(self, watch: _Watch, robot: str, now: float) -> list[EventDraft]:
        """LOST once a robot that connected has said it is lost for STARTING_GRACE_S and
        was never localised since."""
        overdue = now - watch.connected_at > STARTING_GRACE_S
        if watch.localised_once or watch.starting_overdue or watch.localisation != "lost":
            return []
        if not overdue:
            return []
        watch.starting_overdue = True
        text = (
            f"{robot} is lost: not localised {round(now - watch.connected_at)} s after connecting"
        )
        return [self._draft(watch, now, Kind.LOST, Severity.WARNING, robot, text, detail=text)]


def bundle_fetched(robot: str, building: str, map_id: str, number: int, now: float) -> EventDraft:
    """A robot fetched the bundle (map, tags, topology) of ``map_id`` at version ``number``."""
    text = f"{robot} fetched the map bundle of {map_id} v{number}"
    data = {"map_id": map_id, "version": number}
    return EventDraft(
        now, Kind.BUNDLE_FETCHED, Severity.INFO, robot, text, f"robot:{robot}", building, data
    )


def map_version_changed(
    building: str, map_id: str, number: int, reason: str, actor: str, now: float
) -> EventDraft:
    """A sub-map has a new version (an upload, a mapping session, an accepted change, a
    rollback): an event of its building, recorded for each of its robots."""
    text = f"{map_id} is now v{number} ({reason})"
    data = {"map_id": map_id, "version": number, "reason": reason}
    return EventDraft(
        now, Kind.MAP_VERSION_CHANGED, Severity.INFO, None, text, actor, building, data
    )


# Events in recordings: each robot's events on its ``/{robot}/events`` channel as
# ``rosgraph_msgs/Log``, the type Foxglove's and rqt's log panels list with their level.
EVENTS_TOPIC = "events"
EVENT_TYPE = "rosgraph_msgs/Log"
_LOG_LEVELS = {Severity.INFO: 2, Severity.WARNING: 4, Severity.ERROR: 8}
LOG_SEVERITIES = {level: severity for severity, level in _LOG_LEVELS.items()}


def as_log(draft: EventDraft) -> dict[str, Any]:
    """``draft`` as rosbridge JSON of a ``rosgraph_msgs/Log``: the stamp is its time,
    ``level`` its severity, ``name`` its kind, ``msg`` its sentence, and ``topics`` the rest
    as ``key=value`` text (``actor``, ``building``, ``alert`` and each data item, JSON)."""
    sec, nanosec = divmod(int(draft.time * 1e9), 1_000_000_000)
    extra = {"actor": draft.actor, "building": draft.building or "", "alert": draft.alert}
    extra.update(draft.data)
    return {
        "header": {
            "stamp": {"sec": sec, "nanosec": nanosec},
            "frame_id": "",
        },
        "level": _LOG_LEVELS[draft.severity],
        "name": draft.kind.value,
        "msg": draft.message,
        "topics": [f"{key}={_text(value)}" for key, value in extra.items()],
    }


def _text(value: Any) -> str:
    return value if isinstance(value, str) else json.dumps(value, default=str)
