"""What drives one leg at a time (``LegDriver``: the agent's own ``Driver``, or
``robots.agent.stack.StackDriver``, which hands each leg to the robot's own navigation
stack as a goal) and what a tick of it gives (``Drive``, ``DriveState``)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from enum import Enum
from typing import Protocol

from cloudnav_core.se2 import Point, Pose
from robots.agent.navigation.clearance import LocalObstacles
from robots.agent.navigation.commands import Command
from robots.agent.supervisor.submaps import SubMap


class DriveState(Enum):
    MOVING = "moving"
    ARRIVED = "arrived"
    FAILED = "failed"


@dataclass(frozen=True)
class Drive:
    """A tick's command (None: the robot's own navigation stack drives, leave it be)."""

    command: Command | None
    state: DriveState = DriveState.MOVING
    reason: str = ""


class LegDriver(Protocol):
    """What drives one leg at a time: ``Driver``, or a robot's own navigation stack."""

    @property
    def path(self) -> Sequence[Point]:
        """The current global plan, in the map frame."""
        ...

    @property
    def plan_version(self) -> int:
        """Changes whenever ``path`` does."""
        ...

    def drive(
        self,
        target: Pose,
        submap: SubMap | None,
        pose: Pose,
        velocity: Command,
        obstacles: LocalObstacles,
        seconds: float,
        odom: Pose = (0.0, 0.0, 0.0),
    ) -> Drive: ...

    def clear(self) -> None:
        """Forget the target and the plan (a navigation stack's goal is cancelled)."""

    def hold(self) -> Command | None:
        """Stand still for now, keeping the target: the command that does it."""
        ...

    def idle(self) -> Command | None:
        """The command with no goal at all (None: send nothing)."""
