"""Parameters set through rosapi: JSON strings by absolute name, in this process (embedded
mode) or in Redis, shared by every server process (scaled mode).

Who set a parameter decides how long it lives. An admin's parameters persist, as on ROS 1's
parameter server: they are the building's configuration. Anyone else's (a robot's, an
operator's) belong to the connection that set them, as a ROS 2 node's parameters belong to
that node, and go when it closes; a robot sets its own again when it reconnects. Each value
records its owner (none for a persistent one), so a connection that closes removes only the
parameters that are still its own.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any, Protocol

from telemetry.domain.limits import Holdings
from telemetry.domain.names import redis_key

if TYPE_CHECKING:
    from telemetry.rosbridge.connection import Connection


class ParamStore(Protocol):
    async def get(self, name: str) -> str | None: ...

    async def set(self, name: str, value: str, owner: str | None) -> None:
        """Store ``value``; ``owner`` is the connection it lives with, None if persistent."""

    async def delete(self, name: str) -> bool:
        """Remove ``name``; False if it was not set."""

    async def names(self) -> list[str]: ...

    async def release(self, owner: str, names: list[str]) -> None:
        """Remove those of ``names`` that ``owner`` still owns (its connection closed)."""

    async def release_all(self, prefix: str) -> None:
        """Remove every parameter whose owner starts with ``prefix`` (a server process
        that stopped without closing its connections)."""


class MemoryParams:
    def __init__(self) -> None:
        self._values: dict[str, str] = {}
        self._owners: dict[str, str] = {}

    async def get(self, name: str) -> str | None:
        return self._values.get(name)

    async def set(self, name: str, value: str, owner: str | None) -> None:
        self._values[name] = value
        if owner is None:
            self._owners.pop(name, None)
        else:
            self._owners[name] = owner

    async def delete(self, name: str) -> bool:
        self._owners.pop(name, None)
        return self._values.pop(name, None) is not None

    async def names(self) -> list[str]:
        return list(self._values)

    async def release(self, owner: str, names: list[str]) -> None:
        for name in names:
            if self._owners.get(name) == owner:
                await self.delete(name)

    async def release_all(self, prefix: str) -> None:
        for name, owner in list(self._owners.items()):
            if owner.startswith(prefix):
                await self.delete(name)


class RedisParams:
    KEY = redis_key("params")
    OWNERS = redis_key("params", "owners")

    def __init__(self, redis: Any) -> None:
        self.redis = redis

    async def get(self, name: str) -> str | None:
        return _text(await self.redis.hget(self.KEY, name))

    async def set(self, name: str, value: str, owner: str | None) -> None:
        async with self.redis.pipeline(transaction=True) as pipe:
            pipe.hset(self.KEY, name, value)
            if owner is None:
                pipe.hdel(self.OWNERS, name)
            else:
                pipe.hset(self.OWNERS, name, owner)
            await pipe.execute()

    async def delete(self, name: str) -> bool:
        async with self.redis.pipeline(transaction=True) as pipe:
            pipe.hdel(self.KEY, name)
            pipe.hdel(self.OWNERS, name)
            removed, _ = await pipe.execute()
        return bool(removed)

    async def names(self) -> list[str]:
        return [n.decode() if isinstance(n, bytes) else n for n in await self.redis.hkeys(self.KEY)]

    async def release(self, owner: str, names: list[str]) -> None:
        for name in names:
            if _text(await self.redis.hget(self.OWNERS, name)) == owner:
                await self.delete(name)

    async def release_all(self, prefix: str) -> None:
        for name, owner in (await self.redis.hgetall(self.OWNERS)).items():
            if (_text(owner) or "").startswith(prefix):
                await self.delete(_text(name) or "")


def _text(value: Any) -> str | None:
    return value.decode() if isinstance(value, bytes) else value


class Parameters:
    """The process's parameters as rosapi uses them: the store (memory, or Redis when
    scaled), each connection's budget, and the owner a connection's parameters live with
    (None for an admin's, which persist)."""

    def __init__(self, held: Holdings, owner_key: Callable[[str], str]) -> None:
        self.store: ParamStore = MemoryParams()
        self.held = held
        self._owner_key = owner_key

    def owner(self, conn: Connection) -> str | None:
        """Return who owns the parameters ``conn`` sets: the connection itself, named
        uniquely across server processes, or None for an admin's, which persist."""
        return None if conn.principal.admin else self._owner_key(conn.key)

    async def get(self, name: str) -> str | None:
        return await self.store.get(name)

    async def names(self) -> list[str]:
        return await self.store.names()

    async def set(self, conn: Connection, name: str, value: str) -> None:
        """Set ``name``; raises LimitReached past the connection's parameter budget."""
        owner = self.owner(conn)
        if owner is not None:
            self.held.take(conn.key, name, len(name) + len(value))
        await self.store.set(name, value, owner)

    async def delete(self, conn: Connection, name: str) -> bool:
        found = await self.store.delete(name)
        self.held.release(conn.key, name)
        return found

    async def closed(self, conn: Connection) -> None:
        """Remove the parameters ``conn`` still owns: it closed."""
        held = self.held.drop(conn.key)
        owner = self.owner(conn)
        if held and owner is not None:
            await self.store.release(owner, held)
