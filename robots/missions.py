"""Missions: starting one, the operators' commands, and the progress the server records.

The runner (``telemetry.missions``) calls ``goals_due`` and ``record_outcomes`` once a
tick for the robots its process serves; people call ``start`` and ``command``.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Any

from django.db import transaction

from maps.models import Building

from .models import Mission, Robot

COMMANDS = ("pause", "resume", "skip", "cancel")
REACHED = "reached"


class MissionError(ValueError):
    """A mission or a command that cannot be: the reason, for the person asking."""


@dataclass(frozen=True)
class Goal:
    """A goal to send: ``robot`` to ``map_id`` at (x, y, yaw), for ``mission``."""

    mission: int
    robot: str
    map_id: str
    x: float
    y: float
    yaw: float


def check_waypoints(building: Building, waypoints: Any) -> list[dict[str, Any]]:
    """The waypoints as stored; MissionError unless each names a sub-map of ``building``
    and finite x, y (yaw defaults to 0)."""
    if not isinstance(waypoints, list) or not waypoints:
        raise MissionError("waypoints: a list of at least one {map, x, y, yaw}")
    codes = set(building.submaps.values_list("code", flat=True))
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
        clean.append({"map": code, "x": x, "y": y, "yaw": yaw})
    return clean


@transaction.atomic
def start(
    building: Building, robot: Robot, waypoints: Any, mode: str, name: str, by: str
) -> Mission:
    """Start a mission; the robot's active one, if any, is cancelled."""
    if mode not in Mission.Mode.values:
        raise MissionError("mode: once or patrol")
    if not robot.buildings.filter(pk=building.pk).exists():
        raise MissionError(f"{robot.name} is not registered in {building.code}")
    clean = check_waypoints(building, waypoints)
    Mission.objects.filter(robot=robot, state__in=Mission.ACTIVE).update(
        state=Mission.State.CANCELLED, note=f"replaced by a mission of {by}"
    )
    return Mission.objects.create(
        building=building, robot=robot, waypoints=clean, mode=mode, name=name, created_by=by
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


def record_outcomes(outcomes: Mapping[int, str]) -> None:
    """What robots reported of the goals sent for missions: REACHED moves the mission on;
    anything else (the robot's reason for failing) pauses it, with that reason."""
    for mission in Mission.objects.filter(pk__in=outcomes, state=Mission.State.RUNNING):
        outcome = outcomes[mission.pk]
        if outcome == REACHED:
            _advance(mission)
            mission.sent = -1
        else:
            mission.state, mission.note = Mission.State.PAUSED, f"paused: {outcome}"
        mission.save()


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
        goals.append(
            Goal(
                mission.pk,
                mission.robot.name,
                f"{mission.building.code}/{point['map']}",
                point["x"],
                point["y"],
                point["yaw"],
            )
        )
        mission.sent = mission.index
        mission.save(update_fields=["sent", "updated"])
    return goals
