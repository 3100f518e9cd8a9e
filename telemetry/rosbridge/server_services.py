"""The server's own services (``/rosapi/...`` and ``/cloudnav/...``): what a handler gets.

This is the protocol only; which services exist is ``telemetry.rosbridge.service_registry``'s
business, so the modules of services (``rosapi``, ``cloud``) import this one and nothing
imports them back but the registry. A handler gets the narrow parts of the process's
state it may use (``ServerParts``), never the hub.
"""

from __future__ import annotations

from collections.abc import Awaitable, Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Protocol

from telemetry.domain.protocol import Json

if TYPE_CHECKING:
    from telemetry.access.decisions import Access
    from telemetry.pose_checks import PoseChecks
    from telemetry.rosbridge.connection import Connection
    from telemetry.rosbridge.directory import Directory
    from telemetry.rosbridge.params import Parameters
    from telemetry.rosbridge.teleop_locks import TeleopLocks


@dataclass(frozen=True)
class Stopped:
    """What one STOP did: the robot's answer about its goal, the missions it paused, and
    whose teleop lock it withdrew ("" for nobody)."""

    goal: str
    missions: list[str] = field(default_factory=list)
    teleop: str = ""

    def summary(self) -> str:
        parts = ["zero velocity sent", f"goal: {self.goal}"]
        if self.missions:
            parts.append(f"mission paused: {', '.join(self.missions)}")
        if self.teleop:
            parts.append(f"teleop lock of {self.teleop} withdrawn")
        return "; ".join(parts)

    def as_values(self) -> dict[str, Json]:
        return {
            "success": True,
            "message": self.summary(),
            "goal": self.goal,
            "missions": list(self.missions),
            "teleop": self.teleop,
        }


class Halting(Protocol):
    """STOP as a service sees it (``telemetry.stop.RobotStop``)."""

    async def stop(self, robot: str, conn: Connection) -> Stopped:
        """Halt ``robot`` for the person on ``conn`` and say what was done."""
        ...


@dataclass(frozen=True)
class ServerParts:
    """What server services may use of the process: teleop locks, parameters, the
    directory of what is published, served and connected (here and on other processes),
    STOP and the checks of poses sent to robots."""

    teleop: TeleopLocks
    params: Parameters
    directory: Directory
    stop: Halting
    poses: PoseChecks


@dataclass
class ServiceCall:
    """One call to a server service. Handlers return the response ``values`` or raise
    ServiceFailed (or NotAllowed), which the caller receives as ``result: false``."""

    server: ServerParts
    conn: Connection
    access: Access
    name: str
    args: Json

    def arg(self, key: str, default: Json = None) -> Json:
        """Return one request field; requests may come as an object or a one-item list."""
        args = self.args[0] if isinstance(self.args, list) and self.args else self.args
        return args.get(key, default) if isinstance(args, dict) else default


ServiceHandler = Callable[[ServiceCall], Awaitable[Json]]


@dataclass(frozen=True)
class ServerService:
    type: str
    handler: ServiceHandler
