"""The teleop gate: who may drive a robot now. A ``cmd_vel`` passes only from the holder
of the robot's teleop lock, or from the robot itself while nobody holds it; a holder who
falls silent or lets go has the robot stopped (``robots.teleop``)."""

from __future__ import annotations

from robots.teleop import MemoryLockStore, TeleopLocks
from telemetry.config import RosbridgeConfig
from telemetry.connection import Connection
from telemetry.domain import names
from telemetry.domain.bus import TopicBus
from telemetry.domain.messages import twist_2d
from telemetry.domain.protocol import Json
from telemetry.events import EventLog
from telemetry.exceptions import NotAllowed


class TeleopGate:
    """The teleop locks of this process (in Redis when scaled) and the check of each
    ``cmd_vel`` against them."""

    def __init__(self, config: RosbridgeConfig, bus: TopicBus, events: EventLog) -> None:
        self._bus = bus
        self.locks = TeleopLocks(
            MemoryLockStore(),
            stop=self.stop_robot,
            on_event=events.teleop,
            ttl=config.teleop_lock_ttl,
            silence=config.teleop_silence,
            handover=config.teleop_handover,
        )

    async def check_command(self, conn: Connection, name: str, msg: dict[str, Json]) -> None:
        """Let a ``cmd_vel`` through only from the robot's teleop lock holder, or from the
        robot's own token while nobody holds the lock (in any server process).

        Raises NotAllowed otherwise; a holder's command renews the lock and re-arms the
        watchdog.
        """
        robot = names.first_segment(name)
        if conn.principal.robot is not None:
            holder = await self.locks.holder(robot)
            if holder:
                raise NotAllowed(f"{robot} is driven by {holder}, who holds its teleop lock")
            return
        if not self.locks.accepts(robot, conn.key):
            raise NotAllowed(f"{conn.principal.label} does not hold the teleop lock of {robot}")
        self.locks.commanded(robot, moving=_moving(msg))

    def stop_robot(self, robot: str) -> None:
        """Send ``robot`` a zero Twist from the server itself."""
        stop = dict(twist_2d(0.0, 0.0))  # the bus takes a plain, mutable message
        self._bus.publish(None, names.robot_topic(robot, names.CMD_VEL), stop)


def _moving(twist: dict[str, Json]) -> bool:
    """True if a Twist asks for any motion at all."""
    for part in ("linear", "angular"):
        vector = twist.get(part)
        if isinstance(vector, dict) and any(vector.get(axis) for axis in ("x", "y", "z")):
            return True
    return False
