"""What is published, served and connected, in this process and on the others: the
listings rosapi answers."""

from __future__ import annotations

from collections.abc import Callable, Iterable

from telemetry.domain import names
from telemetry.domain.bus import TopicBus
from telemetry.domain.calls import CallTable
from telemetry.rosbridge.cross_process import CrossProcess


class Directory:
    """Names with their types, here and (through the relay) on other server processes."""

    def __init__(
        self,
        bus: TopicBus,
        services: CallTable,
        actions: CallTable,
        own_services: Callable[[], Iterable[tuple[str, str]]],
        robots: Callable[[], Iterable[str]],
        relay: Callable[[], CrossProcess],
    ) -> None:
        self._bus = bus
        self._services = services
        self._actions = actions
        self._own_services = own_services
        self._robots = robots
        self._relay = relay

    async def _everywhere(self, kind: str, here: list[tuple[str, str]]) -> list[tuple[str, str]]:
        """Return ``here`` plus the entries of ``kind`` on other processes (none if alone)."""
        return here + [(name, value) for name, value, _ in await self._relay().entries(kind)]

    async def topics(self) -> list[tuple[str, str]]:
        """``(topic, type)`` of every published topic."""
        return await self._everywhere("topics", list(self._bus.published_topics()))

    async def services(self) -> list[tuple[str, str]]:
        """``(service, type)`` of the server's own services and every advertised one."""
        advertised = await self._everywhere("services", self._services.names())
        return list(self._own_services()) + advertised

    async def actions(self) -> list[tuple[str, str]]:
        return await self._everywhere("actions", self._actions.names())

    async def nodes(self) -> list[str]:
        """The namespace of every connected robot."""
        here = [(robot, "") for robot in self._robots()]
        return [names.robot_namespace(r) for r, _ in await self._everywhere("robots", here)]
