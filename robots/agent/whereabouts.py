"""What the robot says about where it is: its ``localisation`` topic.

A robot with no sub-map does not know where it stands; it publishes no ``pose`` then (a
pose needs a Map ID), so without a word of its own it would just look silent. It says so
on ``/{robot}/localisation`` (``diagnostic_msgs/DiagnosticStatus``, latched), as ROS
nodes report their health:

- ``level`` 0 (OK) when localised, 1 (WARN) when lost or still reading a map;
- ``name`` ``localisation``; ``message`` the state in words, e.g. ``lost, looking for a
  tag`` or ``localised in boccioni_1/CorridorA by tag 0``;
- ``values`` (``diagnostic_msgs/KeyValue``): ``state`` (``lost``, ``entering``,
  ``localised``), ``map_id`` (the sub-map it is in or entering, else empty) and ``source``
  (what placed it: ``tag 0``, ``initial pose``; empty when lost).

A lost robot looks for a tag with its camera all the while; an operator gets it out by
setting its initial pose on a map, or by driving it until its camera reads a tag.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum, IntEnum

from cloudnav_core.messages import DiagnosticStatus, diagnostic_status


class Localisation(Enum):
    LOST = "lost"  # no sub-map: the camera looks for a tag
    ENTERING = "entering"  # a tag was read: fetching the map it names
    LOCALISED = "localised"


class Level(IntEnum):
    """``diagnostic_msgs/DiagnosticStatus`` levels."""

    OK = 0
    WARN = 1


@dataclass(frozen=True)
class Whereabouts:
    """The robot's localisation state, the sub-map it concerns and what placed it there."""

    state: Localisation
    map_id: str = ""
    source: str = ""

    @property
    def message(self) -> str:
        if self.state is Localisation.LOST:
            return "lost, looking for a tag"
        if self.state is Localisation.ENTERING:
            return f"reading the map of {self.map_id} ({self.source})"
        return f"localised in {self.map_id} by {self.source}"

    def status(self) -> DiagnosticStatus:
        """This state as a ``diagnostic_msgs/DiagnosticStatus``."""
        level = Level.OK if self.state is Localisation.LOCALISED else Level.WARN
        values = {"state": self.state.value, "map_id": self.map_id, "source": self.source}
        return diagnostic_status(int(level), "localisation", self.message, values)
