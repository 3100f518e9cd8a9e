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

from typing import Any, Protocol

from telemetry.domain.names import redis_key


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
