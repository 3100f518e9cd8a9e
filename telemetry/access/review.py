"""The access review: what an access change (``telemetry.access.revocation``) does to this
process's connections and video watchers. Those whose credentials were revoked are
closed; every other connection's decisions are taken again, and what it may no longer
hold is withdrawn."""

from __future__ import annotations

import asyncio
import logging
from collections.abc import Awaitable, Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field

from channels.db import database_sync_to_async

from telemetry.access.decisions import Access, Registry
from telemetry.access.revocation import AccessChange, RobotRecord, revoked, robot_records
from telemetry.access.rules import Principal, may_watch
from telemetry.domain import names
from telemetry.domain.bus import TopicBus
from telemetry.rosbridge.connection import Connection
from telemetry.rosbridge.fleet_state import FleetTracker
from telemetry.rosbridge.service_calls import ServiceCalls

logger = logging.getLogger(__name__)


@dataclass
class Client:
    """What the hub keeps of a connection besides the connection itself: its decisions,
    and how to close it when what it was admitted with is revoked."""

    conn: Connection
    robot_pk: int | None = None
    access: Access | None = None
    revoke: Callable[[str], Awaitable[None]] | None = None


@dataclass(eq=False)
class Watcher:
    """A video stream as revocation sees it: who watches which robot's camera; ``ended``
    is set when the stream must stop."""

    principal: Principal
    robot: str
    robot_pk: int | None
    ended: asyncio.Event = field(default_factory=asyncio.Event)


class AccessReview:
    """Applies access changes to the connections of this process (``clients``, by key)
    and to the video streams it serves."""

    def __init__(
        self,
        clients: dict[str, Client],
        leave: Callable[[Connection], Awaitable[None]],
        registry: Registry,
        bus: TopicBus,
        calls: ServiceCalls,
        fleet: FleetTracker,
    ) -> None:
        self._clients = clients
        self._leave = leave
        self._registry = registry
        self._bus = bus
        self._calls = calls
        self._fleet = fleet
        self.watchers: set[Watcher] = set()

    async def access_changed(self, change: AccessChange) -> None:
        """Apply ``change``: read the robots it names again, close what depended on what
        was revoked, and take every other connection's decisions again, withdrawing what
        they may no longer hold."""
        logger.info("access changed: %s", change)
        robots: dict[int, RobotRecord | None] = {}
        if change.robots:
            robots = await database_sync_to_async(robot_records)(change.robots)
        for pk, record in robots.items():
            self._registry.update(pk, record.owner if record is not None else None)
        clients = self._clients.values()
        doomed = [c for c in clients if revoked(c.conn.principal, change, robots)]
        if robots:  # first, so whoever sees a connection close sees the new grants too
            for client in list(clients):
                if client not in doomed:
                    await self._decide_again(client)
        for client in doomed:
            await self._revoke(client, "its credentials were revoked")
        for pk in [pk for pk, record in robots.items() if record is None]:
            self._fleet.forget(pk)  # a deleted robot's row went with it
        for watcher in list(self.watchers):
            if revoked(watcher.principal, change, robots) or not _may_watch(watcher, robots):
                watcher.ended.set()
                self.watchers.discard(watcher)

    async def _revoke(self, client: Client, reason: str) -> None:
        await self._leave(client.conn)
        if client.revoke is not None:
            await client.revoke(reason)

    async def _decide_again(self, client: Client) -> None:
        """Forget ``client``'s decisions and withdraw what it may no longer hold."""
        access, conn = client.access, client.conn
        if access is None:
            return
        access.reset()
        for name, spelling in self._bus.holdings(conn):
            what = "subscribe" if spelling is not None else "advertise"
            written = spelling if spelling is not None else access.shown(name)
            if not await _still(access, what, name, written):
                self._bus.withdraw(conn, name, spelling)
                conn.report("warning", f"{names.outside_realm(name)}: access was withdrawn")
        for table, fail in self._calls.tables():
            for provider in table.served_by(conn):
                if not await _still(access, "advertise_service", provider.name, None):
                    for call in table.unadvertise(provider.name, conn) or []:
                        fail(call, f"{provider.spelling} is no longer served")
        self._calls.publish_directories()

    @contextmanager
    def watching(
        self, principal: Principal, robot: str, robot_pk: int | None
    ) -> Iterator[asyncio.Event]:
        """Count a video stream of ``robot``'s camera watched by ``principal`` while the
        block runs; the event yielded is set when the stream must end (revoked)."""
        watcher = Watcher(principal, robot, robot_pk)
        self.watchers.add(watcher)
        try:
            yield watcher.ended
        finally:
            self.watchers.discard(watcher)


async def _still(access: Access, what: str, name: str, written: str | None) -> bool:
    """True if ``written`` still names ``name`` for ``access``, which may still ``what``."""
    written = written if written is not None else access.shown(name)
    if written is None or await access.resolve(written) != name:
        return False
    return await access.allows(what, name)


def _may_watch(watcher: Watcher, robots: dict[int, RobotRecord | None]) -> bool:
    """True if the watcher may still watch its camera: its robot was not deleted or
    renamed, and still shares a building the watcher sees."""
    if watcher.robot_pk not in robots:
        return True
    now = robots[watcher.robot_pk]
    if now is None or now.owner.robot != watcher.robot:
        return False
    return may_watch(watcher.principal, now.owner)
