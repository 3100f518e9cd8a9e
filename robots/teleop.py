"""Teleop locks and the dead-man watchdog.

One connection at a time holds a robot's teleop lock; only its ``cmd_vel`` reaches the
robot. The lock lapses after ``ttl`` seconds without a command (or on release or
disconnect). When the holder's commands stop for ``silence`` seconds (0.5 s by default),
or it lets go, the robot is sent a zero Twist through ``stop(robot)``.

Locks live in a ``LockStore``: process memory in embedded mode, Redis in scaled mode, so
two server processes never both grant a robot's lock. The process that granted a lock also
keeps it locally, so checking a ``cmd_vel`` costs a dict lookup, not a round trip.
"""

from __future__ import annotations

import asyncio
import time
import uuid
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Protocol

from telemetry.domain.events import Kind
from telemetry.domain.names import redis_key


class LockStore(Protocol):
    async def acquire(self, robot: str, holder: str, ttl: float) -> str:
        """Take or renew the lock if free or ours; return whoever holds it afterwards."""

    async def refresh(self, robot: str, holder: str, ttl: float) -> bool:
        """Extend ``holder``'s lock; False if it no longer holds it."""

    async def release(self, robot: str, holder: str) -> bool:
        """Free ``holder``'s lock; False if it did not hold it."""

    async def holder(self, robot: str) -> str:
        """Return who holds ``robot``'s lock now, or "" when nobody does."""


class MemoryLockStore:
    """Locks of one process (embedded mode)."""

    def __init__(self, clock: Callable[[], float] = time.monotonic) -> None:
        self.clock = clock
        self._locks: dict[str, tuple[str, float]] = {}

    def _current(self, robot: str) -> str | None:
        held = self._locks.get(robot)
        if held is None or held[1] <= self.clock():
            self._locks.pop(robot, None)
            return None
        return held[0]

    async def acquire(self, robot: str, holder: str, ttl: float) -> str:
        current = self._current(robot)
        if current in (None, holder):
            self._locks[robot] = (holder, self.clock() + ttl)
            return holder
        return current or ""

    async def refresh(self, robot: str, holder: str, ttl: float) -> bool:
        return await self.acquire(robot, holder, ttl) == holder

    async def release(self, robot: str, holder: str) -> bool:
        if self._current(robot) != holder:
            return False
        del self._locks[robot]
        return True

    async def holder(self, robot: str) -> str:
        return self._current(robot) or ""


# Compare-and-set scripts: only the holder may extend or delete its lock.
_ACQUIRE = """
local current = redis.call('GET', KEYS[1])
if (not current) or current == ARGV[1] then
  redis.call('SET', KEYS[1], ARGV[1], 'PX', ARGV[2])
  return ARGV[1]
end
return current
"""
_RELEASE = """
if redis.call('GET', KEYS[1]) == ARGV[1] then return redis.call('DEL', KEYS[1]) end
return 0
"""


class RedisLockStore:
    """Locks shared by every server process (scaled mode)."""

    def __init__(self, redis: Any) -> None:
        self.redis = redis

    async def acquire(self, robot: str, holder: str, ttl: float) -> str:
        result = await self.redis.eval(
            _ACQUIRE, 1, redis_key("teleop", robot), holder, int(ttl * 1000)
        )
        return result.decode() if isinstance(result, bytes) else str(result)

    async def refresh(self, robot: str, holder: str, ttl: float) -> bool:
        return await self.acquire(robot, holder, ttl) == holder

    async def release(self, robot: str, holder: str) -> bool:
        return bool(await self.redis.eval(_RELEASE, 1, redis_key("teleop", robot), holder))

    async def holder(self, robot: str) -> str:
        current = await self.redis.get(redis_key("teleop", robot))
        return current.decode() if isinstance(current, bytes) else (current or "")


@dataclass
class _Hold:
    """A lock this process granted to one of its connections."""

    connection: str
    holder: str
    expires: float
    last_command: float
    refreshed: float
    watchdog: asyncio.TimerHandle | None = None
    moving: bool = False


class TeleopLocks:
    """This process's view of the teleop locks, with the watchdog of each lock it holds."""

    def __init__(
        self,
        store: LockStore,
        stop: Callable[[str], None],
        ttl: float = 5.0,
        silence: float = 0.5,
        on_event: Callable[[str, Kind, str], None] | None = None,
    ) -> None:
        self.store = store
        self.stop = stop
        # Told (robot, what, holder's label) of a lock taken, released or lapsed, or a
        # dead-man stop.
        self.on_event = on_event
        self.ttl = ttl
        self.silence = silence
        self.process = uuid.uuid4().hex[:12]
        self._holds: dict[str, _Hold] = {}
        self._tasks: set[asyncio.Task[Any]] = set()

    def _holder(self, connection: str, label: str) -> str:
        return f"{self.process}/{connection}/{label}"

    @staticmethod
    def label_of(holder: str) -> str:
        """Return the principal's label inside a stored holder value."""
        return holder.split("/", 2)[-1]

    async def acquire(self, robot: str, connection: str, label: str) -> tuple[bool, str]:
        """Try to take ``robot``'s lock for ``connection``; return (granted, holder's label)."""
        holder = self._holder(connection, label)
        current = await self.store.acquire(robot, holder, self.ttl)
        if current != holder:
            return False, self.label_of(current)
        now = self._now()
        hold = self._holds.get(robot)
        if hold is None or hold.connection != connection:
            self._forget(robot)
            self._holds[robot] = _Hold(connection, holder, now + self.ttl, now, now)
            self._tell(robot, Kind.TELEOP_TAKEN, holder)
        else:
            hold.expires, hold.refreshed = now + self.ttl, now
        return True, label

    async def holder(self, robot: str) -> str:
        """Return the label of whoever holds ``robot``'s lock, in any process, or ""."""
        current = await self.store.holder(robot)
        return self.label_of(current) if current else ""

    async def release(self, robot: str, connection: str) -> bool:
        """Let go of ``robot``'s lock; the robot is stopped. False if not held by it."""
        hold = self._holds.get(robot)
        if hold is None or hold.connection != connection:
            return False
        self._let_go(robot)
        await self.store.release(robot, hold.holder)
        self._tell(robot, Kind.TELEOP_RELEASED, hold.holder)
        return True

    def accepts(self, robot: str, connection: str) -> bool:
        """True if ``connection`` holds ``robot``'s lock and it has not lapsed."""
        hold = self._holds.get(robot)
        if hold is None or hold.connection != connection:
            return False
        if hold.expires <= self._now():
            self._let_go(robot)
            self._tell(robot, Kind.TELEOP_LAPSED, hold.holder)
            return False
        return True

    def commanded(self, robot: str, moving: bool) -> None:
        """Note a ``cmd_vel`` from the holder: renew the lock and re-arm the watchdog."""
        hold = self._holds[robot]
        now = self._now()
        hold.last_command, hold.expires, hold.moving = now, now + self.ttl, moving
        if now - hold.refreshed > self.ttl / 3:
            hold.refreshed = now
            self._spawn(self._refresh(robot, hold))
        if hold.watchdog is None and moving:
            hold.watchdog = asyncio.get_running_loop().call_later(self.silence, self._check, robot)

    async def _refresh(self, robot: str, hold: _Hold) -> None:
        if (
            not await self.store.refresh(robot, hold.holder, self.ttl)
            and self._holds.get(robot) is hold
        ):
            self._let_go(robot)

    def _check(self, robot: str) -> None:
        hold = self._holds.get(robot)
        if hold is None:
            return
        hold.watchdog = None
        quiet = self._now() - hold.last_command
        if quiet < self.silence:
            hold.watchdog = asyncio.get_running_loop().call_later(
                self.silence - quiet, self._check, robot
            )
        elif hold.moving:
            hold.moving = False
            self.stop(robot)
            self._tell(robot, Kind.DEADMAN_STOP, hold.holder)

    def held_by(self, connection: str) -> list[str]:
        return [robot for robot, hold in self._holds.items() if hold.connection == connection]

    async def drop(self, connection: str) -> None:
        """Release every lock ``connection`` holds (it disconnected)."""
        for robot in self.held_by(connection):
            await self.release(robot, connection)

    def _let_go(self, robot: str) -> None:
        self._forget(robot)
        self.stop(robot)

    def _tell(self, robot: str, what: Kind, holder: str) -> None:
        if self.on_event is not None:
            self.on_event(robot, what, self.label_of(holder))

    def _forget(self, robot: str) -> None:
        hold = self._holds.pop(robot, None)
        if hold is not None and hold.watchdog is not None:
            hold.watchdog.cancel()

    def _spawn(self, coro: Any) -> None:
        task = asyncio.get_running_loop().create_task(coro)
        self._tasks.add(task)
        task.add_done_callback(self._tasks.discard)

    @staticmethod
    def _now() -> float:
        return time.monotonic()
