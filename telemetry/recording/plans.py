"""What each robot records, and what each building keeps, from ``RecordingSettings``."""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

from django.db.models import Prefetch

from maps.models import Building
from robots.models import Robot
from telemetry.models import CAMERA_TOPIC, DEFAULT_RECORDED, RecordingSettings

MB = 1_000_000


@dataclass(frozen=True)
class Plan:
    """The topics (relative to the robot) one robot records; the camera at most every
    ``camera_interval`` seconds."""

    topics: frozenset[str]
    camera_interval: float = 0.0


NOTHING = Plan(frozenset())
DEFAULT = Plan(frozenset(DEFAULT_RECORDED))


@dataclass(frozen=True)
class Retention:
    """What one building keeps: its robots' files at most ``days`` old, ``budget`` bytes."""

    building: str
    robots: frozenset[str]
    days: int
    budget: int


def _plan_of(settings: RecordingSettings | None) -> Plan:
    if settings is None:
        return DEFAULT
    if not settings.enabled:
        return NOTHING
    topics = {str(t) for t in settings.topics}
    interval = 0.0
    if settings.camera_rate > 0:
        topics.add(CAMERA_TOPIC)
        interval = 1.0 / settings.camera_rate
    return Plan(frozenset(topics), interval)


def plan_for(robot: str) -> Plan:
    """The union of what the robot's buildings record (the fastest camera rate wins); a
    robot of no building records the defaults, a robot unknown nothing."""
    return plans_for([robot])[robot]


def plans_for(robots: Iterable[str]) -> dict[str, Plan]:
    """``plan_for`` of each of ``robots``, in two queries whatever their number."""
    wanted = set(robots)
    buildings = Prefetch("buildings", Building.objects.select_related("recording"))
    found = Robot.objects.filter(name__in=wanted).prefetch_related(buildings)
    plans = {robot.name: _union(robot.buildings.all()) for robot in found}
    return {robot: plans.get(robot, NOTHING) for robot in wanted}


def _union(buildings: Iterable[Building]) -> Plan:
    plans = [_plan_of(getattr(b, "recording", None)) for b in buildings]
    if not plans:
        return DEFAULT
    topics = frozenset().union(*(p.topics for p in plans))
    intervals = [p.camera_interval for p in plans if p.camera_interval > 0]
    return Plan(topics, min(intervals) if intervals else 0.0)


def retentions() -> list[Retention]:
    """Every building's retention, with the robots whose files it counts."""
    found = []
    for building in Building.objects.prefetch_related("robots").select_related("recording"):
        settings = getattr(building, "recording", None) or RecordingSettings()
        robots = frozenset(r.name for r in building.robots.all())
        found.append(
            Retention(building.code, robots, settings.retention_days, settings.budget_mb * MB)
        )
    return found
