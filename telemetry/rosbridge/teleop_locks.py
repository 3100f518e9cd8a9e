"""Teleop locks and the dead-man watchdog.

One connection at a time holds a robot's teleop lock; only its ``cmd_vel`` reaches the
robot. The lock lapses ``ttl`` seconds after the last command (or at once on release or
disconnect), whatever else its holder does: asking for the lock again does not renew it,
so a forgotten page blocks no one. The store's copy is renewed for the last command seen
(at most every third of the TTL), so every process sees it lapse at that same moment.
When the holder's commands stop for ``silence`` seconds (0.5 s by default),
or it lets go, the robot is sent a zero Twist through ``stop(robot)``.

Locks live in a ``LockStore``: process memory in embedded mode, Redis in scaled mode, so
two server processes never both grant a robot's lock. The process that granted a lock also
keeps it locally, so checking a ``cmd_vel`` costs a dict lookup, not a round trip.
"""

from __future__ import annotations

import asyncio
import json
import logging
import time
import uuid
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Protocol

from telemetry.domain.events import Kind
from telemetry.domain.names import redis_key

logger = logging.getLogger(__name__)


class LockStore(Protocol):
    async def acquire(self, robot: str, holder: str, ttl: float) -> str:
        """Take the lock for ``ttl`` if free (a lock already ours is left as it is); return
        whoever holds it afterwards."""

    async def refresh(self, robot: str, holder: str, ttl: float) -> bool:
        """Make ``holder``'s lock lapse ``ttl`` from now; False if it no longer holds it
        (a store that lost every lock, as a restarted Redis, holds it for ``holder`` again
        unless another took it meanwhile)."""

    async def release(self, robot: str, holder: str) -> bool:
        """Free ``holder``'s lock; False if it did not hold it."""

    async def holder(self, robot: str) -> str:
        """Return who holds ``robot``'s lock now, or "" when nobody does."""

    async def withdraw(self, robot: str, ttl: float) -> str:
        """Free ``robot``'s lock whoever holds it; return who held it ("" for nobody). For
        ``ttl`` seconds no renewal of the old holder's brings it back."""

    async def ask(self, robot: str, asker: str, deadline: float, ttl: float) -> Request:
        """Record ``asker``'s request for ``robot``'s lock (due at ``deadline``, Unix time;
        kept ``ttl`` s) unless another is pending; return the pending one."""

    async def request(self, robot: str) -> Request | None:
        """Return the request pending for ``robot``'s lock, refused or not, or None."""

    async def answer(self, robot: str, asker: str, refused: bool) -> None:
        """Mark ``asker``'s request refused, or forget it (``refused`` False)."""


@dataclass(frozen=True)
class Request:
    """Someone asking for a held lock: who, when it passes to them unless refused (Unix
    time), and whether the holder refused."""

    asker: str
    deadline: float
    refused: bool = False


class MemoryLockStore:
    """Locks of one process (embedded mode)."""

    def __init__(self, clock: Callable[[], float] = time.monotonic) -> None:
        self.clock = clock
        self._locks: dict[str, tuple[str, float]] = {}
        self._requests: dict[str, tuple[Request, float]] = {}  # robot -> (request, kept until)

    def _current(self, robot: str) -> str | None:
        held = self._locks.get(robot)
        if held is None or held[1] <= self.clock():
            self._locks.pop(robot, None)
            return None
        return held[0]

    async def acquire(self, robot: str, holder: str, ttl: float) -> str:
        current = self._current(robot)
        if current is None:
            self._locks[robot] = (holder, self.clock() + ttl)
            return holder
        return current

    async def refresh(self, robot: str, holder: str, ttl: float) -> bool:
        if self._current(robot) != holder:
            return False
        self._locks[robot] = (holder, self.clock() + ttl)
        return True

    async def release(self, robot: str, holder: str) -> bool:
        if self._current(robot) != holder:
            return False
        del self._locks[robot]
        return True

    async def holder(self, robot: str) -> str:
        return self._current(robot) or ""

    async def withdraw(self, robot: str, ttl: float) -> str:  # noqa: ARG002 (one process: no renewal follows)
        current = self._current(robot) or ""
        self._locks.pop(robot, None)
        return current

    async def ask(self, robot: str, asker: str, deadline: float, ttl: float) -> Request:
        pending = await self.request(robot)
        if pending is None:
            pending = Request(asker, deadline)
            self._requests[robot] = (pending, self.clock() + ttl)
        return pending

    async def request(self, robot: str) -> Request | None:
        held = self._requests.get(robot)
        if held is None or held[1] <= self.clock():
            self._requests.pop(robot, None)
            return None
        return held[0]

    async def answer(self, robot: str, asker: str, refused: bool) -> None:
        held = self._requests.get(robot)
        if held is None or held[0].asker != asker:
            return
        if refused:
            self._requests[robot] = (Request(asker, held[0].deadline, True), held[1])
        else:
            del self._requests[robot]


# Compare-and-set scripts: only the holder may extend or delete its lock. A withdrawn lock
# is an empty value for a TTL (free to acquire, never renewed by its old holder).
_ACQUIRE = """
local current = redis.call('GET', KEYS[1])
if not current or current == '' then
  redis.call('SET', KEYS[1], ARGV[1], 'PX', ARGV[2])
  return ARGV[1]
end
return current
"""
_REFRESH = """
if redis.call('GET', KEYS[1]) == ARGV[1] then
  return redis.call('PEXPIRE', KEYS[1], ARGV[2])
end
return 0
"""
_RELEASE = """
if redis.call('GET', KEYS[1]) == ARGV[1] then return redis.call('DEL', KEYS[1]) end
return 0
"""
_WITHDRAW = """
local current = redis.call('GET', KEYS[1])
redis.call('SET', KEYS[1], '', 'PX', ARGV[1])
return current or ''
"""


class RedisLockStore:
    """Locks shared by every server process (scaled mode). A Redis that restarts empty
    loses them: each holder's process holds its lock again at its next renewal (the
    Redis server's ``run_id`` tells a restart from a lock withdrawn, released or taken)."""

    def __init__(self, redis: Any) -> None:
        self.redis = redis
        # (robot, holder) -> run_id of the Redis server that last confirmed that lock
        self._confirmed: dict[tuple[str, str], str] = {}

    async def _server(self) -> str:
        return str((await self.redis.info("server"))["run_id"])

    async def acquire(self, robot: str, holder: str, ttl: float) -> str:
        result = await self.redis.eval(
            _ACQUIRE, 1, redis_key("teleop", robot), holder, int(ttl * 1000)
        )
        current = result.decode() if isinstance(result, bytes) else str(result)
        if current == holder:
            self._confirmed[robot, holder] = await self._server()
        return current

    async def refresh(self, robot: str, holder: str, ttl: float) -> bool:
        key, milliseconds = redis_key("teleop", robot), max(1, round(ttl * 1000))
        if await self.redis.eval(_REFRESH, 1, key, holder, milliseconds):
            return True
        confirmed_by = self._confirmed.pop((robot, holder), None)
        server = await self._server()
        if confirmed_by in (None, server):
            return False  # lapsed, released, withdrawn or taken on this same Redis
        if not await self.redis.set(key, holder, nx=True, px=milliseconds):
            return False  # another took it after the restart
        self._confirmed[robot, holder] = server
        logger.info("teleop lock of %s held again after Redis restarted", robot)
        return True

    async def release(self, robot: str, holder: str) -> bool:
        self._confirmed.pop((robot, holder), None)
        return bool(await self.redis.eval(_RELEASE, 1, redis_key("teleop", robot), holder))

    async def holder(self, robot: str) -> str:
        current = await self.redis.get(redis_key("teleop", robot))
        return current.decode() if isinstance(current, bytes) else (current or "")

    async def withdraw(self, robot: str, ttl: float) -> str:
        milliseconds = max(1, round(ttl * 1000))
        current = await self.redis.eval(_WITHDRAW, 1, redis_key("teleop", robot), milliseconds)
        held = current.decode() if isinstance(current, bytes) else str(current or "")
        self._confirmed.pop((robot, held), None)
        return held

    async def ask(self, robot: str, asker: str, deadline: float, ttl: float) -> Request:
        value = json.dumps({"asker": asker, "deadline": deadline, "refused": False})
        key = redis_key("teleop_request", robot)
        await self.redis.set(key, value, nx=True, px=max(1, round(ttl * 1000)))
        return await self.request(robot) or Request(asker, deadline)

    async def request(self, robot: str) -> Request | None:
        value = await self.redis.get(redis_key("teleop_request", robot))
        return Request(**json.loads(value)) if value else None

    async def answer(self, robot: str, asker: str, refused: bool) -> None:
        key = redis_key("teleop_request", robot)
        pending = await self.request(robot)
        if pending is None or pending.asker != asker:
            return
        if not refused:
            await self.redis.delete(key)
            return
        value = json.dumps({"asker": asker, "deadline": pending.deadline, "refused": True})
        await self.redis.set(key, value, xx=True, keepttl=True)


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
    refresh: asyncio.TimerHandle | None = None  # the store's renewal, when one is planned
    lapse: asyncio.TimerHandle | None = None


class TeleopLocks:
    """This process's view of the teleop locks, with the watchdog of each lock it holds."""

    def __init__(
        self,
        store: LockStore,
        stop: Callable[[str], None],
        ttl: float = 5.0,
        silence: float = 0.5,
        on_event: Callable[[str, Kind, str], None] | None = None,
        handover: float = 5.0,
    ) -> None:
        self.store = store
        self.stop = stop
        # Told (robot, what, holder's label) of a lock taken, released or lapsed, or a
        # dead-man stop.
        self.on_event = on_event
        self.ttl = ttl
        self.silence = silence
        self.handover = handover
        self.process = uuid.uuid4().hex[:12]
        self._holds: dict[str, _Hold] = {}
        # (robot, connection) -> until when that connection, whose lock lapsed, waits
        self._lapsed: dict[tuple[str, str], float] = {}
        self._tasks: set[asyncio.Task[Any]] = set()

    def _holder(self, connection: str, label: str) -> str:
        return f"{self.process}/{connection}/{label}"

    @staticmethod
    def label_of(holder: str) -> str:
        """Return the principal's label inside a stored holder value."""
        return holder.split("/", 2)[-1]

    async def acquire(self, robot: str, connection: str, label: str) -> tuple[bool, str]:
        """Try to take ``robot``'s lock for ``connection``; return (granted, holder's label).

        A connection whose lock lapsed may not take it again for ``ttl`` (granted False,
        holder ""): a page that keeps asking leaves the others that time to take it."""
        if self._lapsed.get((robot, connection), 0.0) > self._now():
            return False, ""
        self._lapsed.pop((robot, connection), None)
        holder = self._holder(connection, label)
        current = await self.store.acquire(robot, holder, self.ttl)
        if current != holder:
            return False, self.label_of(current)
        hold = self._holds.get(robot)
        if hold is None or hold.connection != connection:
            self._forget(robot)
            now = self._now()
            hold = self._holds[robot] = _Hold(connection, holder, now + self.ttl, now, now)
            self._arm_lapse(robot, hold)
            self._tell(robot, Kind.TELEOP_TAKEN, holder)
        # asking again renews nothing: only commands keep a lock (a forgotten page lapses)
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

    async def withdraw(self, robot: str, keep: str) -> str:
        """Take ``robot``'s lock from whoever holds it but connection ``keep`` (someone
        pressed STOP there): their commands no longer pass. Return the label of the holder
        it was taken from, or "".

        A holder on another process keeps its local grant until its next refresh finds
        the lock gone (at most a third of the TTL while it drives)."""
        hold = self._holds.get(robot)
        if hold is not None and hold.connection == keep:
            return ""
        self._forget(robot)
        held = await self.store.withdraw(robot, self.ttl)
        return self.label_of(held) if held else ""

    async def ask(
        self, robot: str, connection: str, label: str
    ) -> tuple[bool, str, str, float | None]:
        """Ask for ``robot``'s lock: granted at once if free; else its holder is told
        (``request``) and the lock passes to the asker ``handover`` seconds after the
        first asking, when the asker asks again, unless the holder refused first. Return
        (granted, holder's label, what is going on, seconds before it passes or None when
        it will not)."""
        granted, holder = await self.acquire(robot, connection, label)
        if granted or not holder:
            return granted, holder, "", None
        me = self._holder(connection, label)
        pending = await self.store.ask(robot, me, time.time() + self.handover, 2 * self.handover)
        if pending.asker != me:
            return False, holder, f"{self.label_of(pending.asker)} asked first", None
        if pending.refused:
            return False, holder, f"{holder} keeps control", None
        left = pending.deadline - time.time()
        if left > 0:
            text = f"{holder} is asked; control passes to you in {left:.0f} s"
            return False, holder, text, left
        await self.store.answer(robot, me, refused=False)
        granted, _ = await self.take(robot, connection, label)
        return granted, label if granted else holder, "", None

    async def request(self, robot: str) -> tuple[str, float] | None:
        """Who asks for ``robot``'s lock and the seconds before it passes to them, or None
        (none asks, or the holder refused)."""
        pending = await self.store.request(robot)
        if pending is None or pending.refused:
            return None
        return self.label_of(pending.asker), max(0.0, pending.deadline - time.time())

    async def refuse(self, robot: str, connection: str) -> str:
        """The holder on ``connection`` keeps its lock: the pending request is refused.
        Return the asker's label ("" if none asked or ``connection`` holds nothing)."""
        hold = self._holds.get(robot)
        pending = await self.store.request(robot)
        if hold is None or hold.connection != connection or pending is None:
            return ""
        await self.store.answer(robot, pending.asker, refused=True)
        return self.label_of(pending.asker)

    async def take(self, robot: str, connection: str, label: str) -> tuple[bool, str]:
        """Take ``robot``'s lock for ``connection`` from whoever holds it (an admin's
        right); the robot is stopped. Return (granted, the label it was taken from)."""
        taken_from = await self.withdraw(robot, keep=connection)
        self.stop(robot)
        self._lapsed.pop((robot, connection), None)
        granted, _ = await self.acquire(robot, connection, label)
        return granted, taken_from

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
        loop = asyncio.get_running_loop()
        if hold.refresh is None:
            # Renew the store for the last command seen, at most every third of the TTL:
            # a renewal planned now runs after this command, so none is ever missed.
            delay = max(0.0, hold.refreshed + self.ttl / 3 - now)
            hold.refresh = loop.call_later(delay, self._begin_refresh, robot, hold)
        if hold.watchdog is None and moving:
            hold.watchdog = loop.call_later(self.silence, self._check, robot)

    def _begin_refresh(self, robot: str, hold: _Hold) -> None:
        hold.refresh = None  # a command from now on plans the next renewal
        self._spawn(self._refresh(robot, hold))

    async def _refresh(self, robot: str, hold: _Hold) -> None:
        """Make the store's lock lapse ``ttl`` after the last command, as the local one."""
        hold.refreshed = self._now()
        left = hold.last_command + self.ttl - hold.refreshed
        if (
            left <= 0 or not await self.store.refresh(robot, hold.holder, left)
        ) and self._holds.get(robot) is hold:
            self._let_go(robot)

    def _arm_lapse(self, robot: str, hold: _Hold) -> None:
        delay = max(0.0, hold.expires - self._now())
        hold.lapse = asyncio.get_running_loop().call_later(delay, self._lapse, robot, hold)

    def _lapse(self, robot: str, hold: _Hold) -> None:
        """The lock's time is up unless a command came since: let go and say so."""
        if self._holds.get(robot) is not hold:
            return
        if hold.expires > self._now():
            self._arm_lapse(robot, hold)
            return
        self._let_go(robot)
        self._lapsed[robot, hold.connection] = self._now() + self.ttl
        self._spawn(self.store.release(robot, hold.holder))
        self._tell(robot, Kind.TELEOP_LAPSED, hold.holder)

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
        for key in [key for key in self._lapsed if key[1] == connection]:
            del self._lapsed[key]

    def _let_go(self, robot: str) -> None:
        self._forget(robot)
        self.stop(robot)

    def _tell(self, robot: str, what: Kind, holder: str) -> None:
        if self.on_event is not None:
            self.on_event(robot, what, self.label_of(holder))

    def _forget(self, robot: str) -> None:
        hold = self._holds.pop(robot, None)
        if hold is None:
            return
        for timer in (hold.watchdog, hold.refresh, hold.lapse):
            if timer is not None:
                timer.cancel()

    def _spawn(self, coro: Any) -> None:
        task = asyncio.get_running_loop().create_task(coro)
        self._tasks.add(task)
        task.add_done_callback(self._finished)

    def _finished(self, task: asyncio.Task[Any]) -> None:
        """Forget a finished store call; one that failed (the store out of reach: the
        lock was let go here already, and the store's copy lapses by its TTL) is said in
        one line, not left to asyncio's "exception was never retrieved"."""
        self._tasks.discard(task)
        if not task.cancelled() and (error := task.exception()) is not None:
            logger.warning("teleop: the lock store did not answer (%s)", error)

    @staticmethod
    def _now() -> float:
        return time.monotonic()
