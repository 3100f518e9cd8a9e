"""What the Maps Supervisor tells the driver each tick (``Leg`` of a ``LegKind``) and the
goal it works toward (``Destination``)."""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum

from cloudnav_core.se2 import Pose
from robots.agent.supervisor.submaps import SubMap


class LegKind(Enum):
    HOLD = "hold"  # stand still: a bundle is on its way
    SEARCH = "search"  # turn on the spot, looking for a marker
    APPROACH = "approach"  # drive to a point in front of a tag, to read it
    FINAL = "final"  # drive to the goal itself
    FAIL = "fail"  # the goal cannot be reached


@dataclass(frozen=True)
class Leg:
    """What to drive to now: ``target`` is a pose in the estimate's frame (the current
    sub-map's, or odometry's when lost); ``marker`` the tag approached; ``text`` says
    what is going on, for ``nav_status``."""

    kind: LegKind
    text: str
    target: Pose | None = None
    marker: int | None = None
    submap: SubMap | None = None  # where to plan; None: drive straight by sight


@dataclass(frozen=True)
class Destination:
    """A goal's sub-map and pose in it."""

    building: str
    code: str
    pose: Pose

    @classmethod
    def parse(cls, map_id: str, pose: Pose) -> Destination | None:
        """From a goal's frame ``building/code``; None if it is not one."""
        building, slash, code = map_id.strip().partition("/")
        return cls(building, code, pose) if slash and building and code else None
