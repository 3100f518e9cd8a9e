"""Parameters set through rosapi: JSON strings by absolute name, in this process (embedded
mode) or in Redis, shared by every server process (scaled mode)."""

from __future__ import annotations

from typing import Any, Protocol

from telemetry.domain.names import redis_key


class ParamStore(Protocol):
    async def get(self, name: str) -> str | None: ...

    async def set(self, name: str, value: str) -> None: ...

    async def delete(self, name: str) -> bool:
        """Remove ``name``; False if it was not set."""

    async def names(self) -> list[str]: ...


class MemoryParams:
    def __init__(self) -> None:
        self._values: dict[str, str] = {}

    async def get(self, name: str) -> str | None:
        return self._values.get(name)

    async def set(self, name: str, value: str) -> None:
        self._values[name] = value

    async def delete(self, name: str) -> bool:
        return self._values.pop(name, None) is not None

    async def names(self) -> list[str]:
        return list(self._values)


class RedisParams:
    KEY = redis_key("params")

    def __init__(self, redis: Any) -> None:
        self.redis = redis

    async def get(self, name: str) -> str | None:
        value = await self.redis.hget(self.KEY, name)
        return value.decode() if isinstance(value, bytes) else value

    async def set(self, name: str, value: str) -> None:
        await self.redis.hset(self.KEY, name, value)

    async def delete(self, name: str) -> bool:
        return bool(await self.redis.hdel(self.KEY, name))

    async def names(self) -> list[str]:
        return [n.decode() if isinstance(n, bytes) else n for n in await self.redis.hkeys(self.KEY)]
