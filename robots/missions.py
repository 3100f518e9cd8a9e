"""Missions: starting one, the operators' commands, and the progress the server records.

The runner (``telemetry.missions``) calls ``goals_due`` and ``record_outcomes`` once a
tick for the robots its process serves; people call ``start`` and ``command``.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from functools import partial
from typing import Any

from django.db import transaction

from cloudnav_django.batches import write_batch
from maps.domain.planning import PoseRefused
from maps.models import Building, SubMap
from maps.services import goal_check_of

from .models import Mission, Robot

COMMANDS = ("pause", "resume", "skip", "cancel")
REACHED = "reached"
# The outcome of a waypoint not reached within its mission's time limit.
TIMED_OUT = "timed out"
# The longest note a mission keeps (a robot's reason for failing may be longer).
NOTE_MAX = Mission._meta.get_field("note").max_length or 300


class MissionError(ValueError):
    """A mission or a command that cannot be: the reason, for the person asking, and the
    request's field at fault (``mission`` when it is no one field)."""

    def __init__(self, message: str, field: str = "mission") -> None:
        super().__init__(message)
        self.field = field


class RobotBusyElsewhere(MissionError):
    """The robot runs a mission of another building: only that building's people may
    replace it (they may be another tenant; their mission is not theirs to end)."""


@dataclass(frozen=True)
class Goal:
    """A goal to send: ``robot`` to ``map_id`` at (x, y, yaw), for ``mission``; ``note``
    says why it is not the waypoint itself (moved off a spot another robot holds);
    ``time_limit`` (s, 0: none) and ``on_timeout`` are the mission's (``Mission``)."""

    mission: int
    robot: str
    map_id: str
    x: float
    y: float
    yaw: float
    note: str = ""
    time_limit: float = 0.0
    on_timeout: str = "pause"


def check_waypoints(building: Building, waypoints: Any) -> list[dict[str, Any]]:
    """The waypoints as stored; MissionError unless each names a sub-map of ``building``
    and finite x, y (yaw defaults to 0)."""
    if not isinstance(waypoints, list) or not waypoints:
        raise MissionError("waypoints: a list of at least one {map, x, y, yaw}")
    submaps = {submap.code: submap for submap in building.submaps.all()}
    codes = set(submaps)
    clean = []
    for n, point in enumerate(waypoints, 1):
        try:
            x, y, yaw = float(point["x"]), float(point["y"]), float(point.get("yaw", 0.0))
            code = str(point["map"])
        except (KeyError, TypeError, ValueError):
            raise MissionError(f"waypoint {n}: needs map, x, y (numbers) and yaw") from None
        if code not in codes:
            raise MissionError(f"waypoint {n}: {building.code} has no sub-map {code!r}")
        if not all(abs(v) < 1e6 for v in (x, y, yaw)):
            raise MissionError(f"waypoint {n}: x, y and yaw must be finite")
        _check_reachable(submaps[code], n, x, y)
        clean.append({"map": code, "x": x, "y": y, "yaw": yaw})
    return clean


def _check_reachable(submap: SubMap, n: int, x: float, y: float) -> None:
    """MissionError (field ``waypoints``) unless a robot could stand at (x, y) of
    ``submap`` (``maps.domain.planning.GoalCheck``)."""
    try:
        goal_check_of(submap).check((x, y), f"waypoint {n}")
    except PoseRefused as refused:
        raise MissionError(f"{refused} ({submap.map_id})", field="waypoints") from None


@transaction.atomic
def start(
    building: Building,
    robot: Robot,
    waypoints: Any,
    mode: str,
    name: str,
    by: str,
    *,
    time_limit: float = 300.0,
    on_timeout: str = "pause",
) -> Mission:
    """Start a mission; the robot's active one, if any, is cancelled. Each waypoint has
    ``time_limit`` seconds (0: no limit), then is skipped or pauses it (``on_timeout``)."""
    if on_timeout not in Mission.OnTimeout.values:
        raise MissionError("on_timeout: skip or pause", field="on_timeout")
    if not 0.0 <= time_limit < 1e6:
        raise MissionError("time_limit: seconds, 0 (no limit) or more", field="time_limit")
    if mode not in Mission.Mode.values:
        raise MissionError("mode: once or patrol")
    if not robot.buildings.filter(pk=building.pk).exists():
        raise MissionError(f"{robot.name} is not registered in {building.code}")
    clean = check_waypoints(building, waypoints)
    active = Mission.objects.select_for_update().filter(robot=robot, state__in=Mission.ACTIVE)
    if active.exclude(building=building).exists():
        raise RobotBusyElsewhere(
            f"{robot.name} is on a mission of another building; it can be replaced only there"
        )
    active.update(state=Mission.State.CANCELLED, note=f"replaced by a mission of {by}")
    return Mission.objects.create(
        building=building,
        robot=robot,
        waypoints=clean,
        mode=mode,
        name=name,
        created_by=by,
        time_limit=time_limit,
        on_timeout=on_timeout,
    )


def command(mission: Mission, what: str, by: str) -> Mission:
    """Pause, resume, skip (to the next waypoint) or cancel an active mission."""
    if mission.state not in Mission.ACTIVE:
        raise MissionError(f"the mission is {mission.state}")
    if what == "pause":
        mission.state, mission.note = Mission.State.PAUSED, f"paused by {by}"
    elif what == "resume":
        mission.state, mission.sent, mission.note = Mission.State.RUNNING, -1, ""
    elif what == "skip":
        _advance(mission)
        mission.sent = -1
        mission.note = f"waypoint skipped by {by}"
    elif what == "cancel":
        mission.state, mission.note = Mission.State.CANCELLED, f"cancelled by {by}"
    else:
        raise MissionError(f"unknown command {what!r}: one of {', '.join(COMMANDS)}")
    mission.save()
    return mission


@transaction.atomic
def pause_for_stop(robot: str, by: str, by_buildings: frozenset[int]) -> list[str]:
    """Pause every running mission of ``robot``: someone pressed STOP. The note names
    ``by`` in missions of ``by_buildings`` (where that person is known) and no one
    elsewhere. Return the paused missions' names (or ``#id`` for unnamed ones)."""
    paused = []
    running = Mission.objects.filter(robot__name=robot, state=Mission.State.RUNNING)
    for mission in running.select_for_update():
        who = by if mission.building_id in by_buildings else "an operator of another building"
        mission.state, mission.note = Mission.State.PAUSED, f"paused: {robot} stopped by {who}"
        mission.save(update_fields=["state", "note", "updated"])
        paused.append(mission.name or f"#{mission.pk}")
    return paused


def _advance(mission: Mission) -> None:
    """On to the next waypoint: the next lap of a patrol, or done."""
    mission.index += 1
    if mission.index < len(mission.waypoints):
        return
    if mission.mode == Mission.Mode.PATROL:
        mission.index, mission.laps = 0, mission.laps + 1
    else:
        mission.index, mission.state = len(mission.waypoints) - 1, Mission.State.DONE
        mission.note = "every waypoint reached"


def record_outcomes(outcomes: Mapping[int, str]) -> set[int]:
    """What robots reported of the goals sent for missions: REACHED moves the mission on;
    TIMED_OUT skips the waypoint or pauses the mission (its ``on_timeout``); anything else
    (the robot's reason for failing) pauses it, with that reason. Returns the missions
    whose outcome was recorded (those still running). Mission by mission where the
    database refuses one (``write_batch``); raises ``BatchInterrupted`` with the missions
    not recorded when the database cannot be reached."""
    recorded: set[int] = set()
    write = partial(_record, outcomes=outcomes, recorded=recorded)
    refused = write_batch(sorted(outcomes), write, "a mission's outcome")
    return recorded - set(refused)


def _record(pks: Sequence[int], outcomes: Mapping[int, str], recorded: set[int]) -> None:
    # read again on each try: a try that failed changed nothing (its transaction is gone)
    for mission in Mission.objects.filter(pk__in=pks, state=Mission.State.RUNNING):
        recorded.add(mission.pk)
        outcome = outcomes[mission.pk]
        if outcome == REACHED:
            _advance(mission)
            mission.sent = -1
        elif outcome == TIMED_OUT:
            _timed_out(mission)
        else:
            mission.state, mission.note = Mission.State.PAUSED, f"paused: {outcome}"[:NOTE_MAX]
        mission.save()


def _timed_out(mission: Mission) -> None:
    """The current waypoint was not reached within the time limit: skipped or paused."""
    late = f"waypoint {mission.index + 1} not reached within {mission.time_limit:g} s"
    if mission.on_timeout == Mission.OnTimeout.SKIP:
        _advance(mission)
        mission.sent, mission.note = -1, f"{late}: skipped"
    else:
        mission.state, mission.note = Mission.State.PAUSED, f"paused: {late}"


def _refusal(mission: Mission, point: Mapping[str, Any]) -> str:
    """Why the mission's waypoint ``point`` cannot be sent now (its sub-map is gone or
    changed under it), or ""."""
    submap = mission.building.submaps.filter(code=point["map"]).first()
    if submap is None:
        return (
            f"waypoint {mission.index + 1}: {mission.building.code} has no sub-map {point['map']!r}"
        )
    try:
        _check_reachable(submap, mission.index + 1, point["x"], point["y"])
    except MissionError as error:
        return str(error)
    return ""


def on_a_mission(robot: str) -> bool:
    """Whether ``robot`` runs a mission (its next waypoint moves it on)."""
    return Mission.objects.filter(robot__name=robot, state=Mission.State.RUNNING).exists()


def goals_due(robots: Iterable[str]) -> list[Goal]:
    """The goals to send now to ``robots``: each running mission's current waypoint not yet
    sent; marked sent."""
    goals = []
    running = Mission.objects.filter(
        robot__name__in=list(robots), state=Mission.State.RUNNING
    ).select_related("robot", "building")
    for mission in running:
        if mission.sent == mission.index:
            continue
        point = mission.waypoints[mission.index]
        refused = _refusal(mission, point)
        if refused:
            mission.state, mission.note = Mission.State.PAUSED, f"paused: {refused}"
            mission.save(update_fields=["state", "note", "updated"])
            continue
        goals.append(
            Goal(
                mission.pk,
                mission.robot.name,
                f"{mission.building.code}/{point['map']}",
                point["x"],
                point["y"],
                point["yaw"],
                time_limit=mission.time_limit,
                on_timeout=mission.on_timeout,
            )
        )
        mission.sent = mission.index
        mission.save(update_fields=["sent", "updated"])
    return goals
