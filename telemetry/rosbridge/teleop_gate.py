"""The teleop gate: who may drive a robot now. A ``cmd_vel`` passes only from the holder
of the robot's teleop lock, or from the robot itself while nobody holds it; a holder who
falls silent or lets go has the robot stopped (``telemetry.rosbridge.teleop_locks``) by the
holder's process.
When that process dies (scaled mode) it stops nothing: the process the robot is connected
to watches the commands that reach it from elsewhere and stops the robot itself once they
fall silent while it moves (``ElsewhereWatch``)."""

from __future__ import annotations

import asyncio
from collections.abc import Callable

from cloudnav_core import topics
from cloudnav_core.messages import twist_2d
from telemetry.domain import names
from telemetry.domain.bus import TopicBus
from telemetry.domain.protocol import Json
from telemetry.events import EventLog
from telemetry.exceptions import NotAllowed
from telemetry.rosbridge.config import RosbridgeConfig
from telemetry.rosbridge.connection import Connection
from telemetry.rosbridge.teleop_locks import MemoryLockStore, TeleopLocks

# How much later than the holder's own process the robot's steps in: the relay's delay on a
# loaded machine, so that a holder driving steadily is never stopped by it.
RELAY_GRACE = 1.0


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
        self.elsewhere = ElsewhereWatch(config.teleop_silence + RELAY_GRACE, self.stop_robot)

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

    def commanded_elsewhere(self, robot: str, msg: dict[str, Json]) -> None:
        """A ``cmd_vel`` to ``robot``, connected here, that passed the gate of another
        process."""
        self.elsewhere.commanded(robot, _moving(msg))

    def stop_robot(self, robot: str) -> None:
        """Send ``robot`` a zero Twist from the server itself."""
        stop = dict(twist_2d(0.0, 0.0))  # the bus takes a plain, mutable message
        self._bus.publish(None, topics.robot_topic(robot, topics.CMD_VEL), stop)


def _moving(twist: dict[str, Json]) -> bool:
    """True if a Twist asks for any motion at all."""
    for part in ("linear", "angular"):
        vector = twist.get(part)
        if isinstance(vector, dict) and any(vector.get(axis) for axis in ("x", "y", "z")):
            return True
    return False


class ElsewhereWatch:
    """The dead-man of commands that come from another process: a robot they set moving is
    stopped here ``silence`` seconds after the last of them, unless one that stops it came
    first (the holder's process, alive, sends that itself ``RELAY_GRACE`` earlier)."""

    def __init__(self, silence: float, stop: Callable[[str], None]) -> None:
        self.silence = silence
        self.stop = stop
        self._last: dict[str, float] = {}  # moving robots -> when the last command came
        self._timers: dict[str, asyncio.TimerHandle] = {}

    def commanded(self, robot: str, moving: bool) -> None:
        loop = asyncio.get_running_loop()
        if not moving:
            self._forget(robot)
            return
        self._last[robot] = loop.time()
        if robot not in self._timers:
            self._timers[robot] = loop.call_later(self.silence, self._check, robot)

    def _check(self, robot: str) -> None:
        loop = asyncio.get_running_loop()
        quiet = loop.time() - self._last[robot]
        if quiet < self.silence:
            self._timers[robot] = loop.call_later(self.silence - quiet, self._check, robot)
            return
        self._forget(robot)
        self.stop(robot)

    def _forget(self, robot: str) -> None:
        self._last.pop(robot, None)
        timer = self._timers.pop(robot, None)
        if timer is not None:
            timer.cancel()
