"""Who is connecting, and what each name's owner allows them: the ORM side of the rosbridge.

``authenticate`` runs once per connection. The process's ``Registry`` knows which robot
owns which name; ``Access`` keeps one connection's decisions, so after the first frame on
a name no frame on it touches the database again. When access changes (a robot appears,
is renamed, relinked or deleted: ``telemetry.access.revocation``) the registry is updated and
every connection's decisions are taken again.

A name no robot owns lives in the connection's realm (``names.in_realm``): one building,
the one asked with ``?building=CODE`` when connecting or else the first of the
connection's buildings by code. Clients never see a realm: they write and read plain names.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any
from urllib.parse import parse_qs, urlsplit

from channels.db import database_sync_to_async
from django.conf import settings
from django.http.request import split_domain_port, validate_host

from maps.access import Role, buildings_for, global_role, role_in
from robots.models import Robot
from robots.principal import RobotPrincipal
from robots.services import robot_for_token
from telemetry.access import rules
from telemetry.access.rules import Owner, Principal
from telemetry.domain import names
from telemetry.exceptions import NotAllowed


@dataclass(frozen=True, slots=True)
class Identity:
    """An authenticated connection: its principal, and its robot's primary key if a robot."""

    principal: Principal
    robot_pk: int | None = None


def _headers(scope: Mapping[str, Any]) -> dict[bytes, bytes]:
    return {name.lower(): value for name, value in scope.get("headers", [])}


def token_of(scope: Mapping[str, Any]) -> str | None:
    """Return the robot token from ``?token=`` or ``Authorization: Token ...``, if any."""
    query: dict[str, list[str]] = parse_qs(scope.get("query_string", b"").decode("latin-1"))
    if query.get("token"):
        return query["token"][0]
    header = _headers(scope).get(b"authorization", b"").decode("latin-1").split()
    if len(header) == 2 and header[0].lower() == "token":
        return header[1]
    return None


def origin_allowed(scope: Mapping[str, Any]) -> bool:
    """True if the handshake's ``Origin`` is this site, as the browser saw it.

    That is the scheme, host and port the request came to (``Host``, a host in
    ``ALLOWED_HOSTS``; ``ws`` is ``http``, ``wss`` is ``https``), or one of
    ``CSRF_TRUSTED_ORIGINS`` (the public origin, behind a proxy that ends TLS). A session
    cookie rides along with any page's WebSocket, so a session is only trusted from our
    own pages; tokens are not ambient and need no origin.
    """
    headers = _headers(scope)
    origin = _origin_of(headers.get(b"origin", b"").decode("latin-1"))
    if origin is None:
        return False
    if origin in {_origin_of(trusted) for trusted in settings.CSRF_TRUSTED_ORIGINS}:
        return True
    host = headers.get(b"host", b"").decode("latin-1")
    domain, _ = split_domain_port(host)
    if not domain or not validate_host(domain, settings.ALLOWED_HOSTS):
        return False
    scheme = "https" if scope.get("scheme") in ("wss", "https") else "http"
    return origin == _origin_of(f"{scheme}://{host}")


_DEFAULT_PORTS = {"http": 80, "https": 443}


def _origin_of(url: str) -> tuple[str, str, int] | None:
    """Return ``url``'s (scheme, host, port), the port made explicit; None if it has none."""
    try:
        parts = urlsplit(url)
        scheme, host = parts.scheme.lower(), parts.hostname
        port = parts.port or _DEFAULT_PORTS.get(scheme)
    except ValueError:  # a port that is not a number, a broken IPv6 literal
        return None
    if not host or port is None:
        return None
    return scheme, host, port


async def authenticate(scope: Mapping[str, Any]) -> Identity | None:
    """Return who is connecting, or None if the connection must be refused.

    A token, when given, decides alone: a robot's token admits that robot, any other token
    nothing. Without one, a signed-in person with a role, on one of our own pages, is
    admitted. Everyone else (anonymous, no role, foreign origin) is refused.
    """
    token = token_of(scope)
    building = asked_building(scope)
    if token is not None:
        robot: Identity | None = await database_sync_to_async(robot_identity)(token, building)
        return robot
    user = scope.get("user")
    if user is None or not user.is_authenticated or not origin_allowed(scope):
        return None
    session = getattr(scope.get("session"), "session_key", None)
    person: Identity | None = await database_sync_to_async(person_identity)(user, session, building)
    return person


def asked_building(scope: Mapping[str, Any]) -> str | None:
    """Return the building code of ``?building=``, if any: the connection's realm."""
    query = parse_qs(scope.get("query_string", b"").decode("latin-1"))
    return query["building"][0] if query.get("building") else None


def _realm(buildings: list[Any], asked: str | None) -> str:
    """The realm of a connection: the building asked if it is one of ``buildings``, else
    the first of them by code; those of no building (no tenant's) share one realm."""
    ordered = sorted(buildings, key=lambda b: b.code)
    chosen = next((b for b in ordered if b.code == asked), ordered[0] if ordered else None)
    return names.building_realm(chosen.pk) if chosen is not None else names.NO_BUILDING


def robot_identity(token: str, building: str | None = None) -> Identity | None:
    robot = robot_for_token(token)
    if robot is None:
        return None
    buildings = list(buildings_for(RobotPrincipal(robot)))
    principal = Principal(
        label=f"robot:{robot.name}",
        robot=robot.name,
        buildings=frozenset(b.pk for b in buildings),
        realm=_realm(buildings, building),
        robot_pk=robot.pk,
        credential=robot.token_hash,
    )
    return Identity(principal=principal, robot_pk=robot.pk)


def person_identity(
    user: Any, session: str | None = None, building: str | None = None
) -> Identity | None:
    role = global_role(user)
    if role is Role.NONE:
        return None
    buildings = list(buildings_for(user))
    drive = frozenset(b.pk for b in buildings if role_in(user, b) >= Role.OPERATOR)
    principal = Principal(
        label=f"user:{user.get_username()}",
        robot=None,
        buildings=frozenset(b.pk for b in buildings),
        drive_buildings=drive,
        admin=role >= Role.ADMIN,
        realm=_realm(buildings, building),
        user_id=user.pk,
        credential=session,
    )
    return Identity(principal=principal)


def owner_named(segment: str) -> Owner | None:
    """Return the robot called ``segment`` with its buildings, or None if there is none."""
    robot = Robot.objects.filter(name=segment).first()
    if robot is None:
        return None
    buildings = frozenset(robot.buildings.values_list("pk", flat=True))
    return Owner(robot.name, buildings, robot.pk)


class Registry:
    """Which robot owns which name, in this process: learnt from the database on a miss,
    and updated when access changes (``update``), never read again per message."""

    def __init__(self) -> None:
        self._by_name: dict[str, Owner] = {}
        self._names: dict[int, str] = {}

    def owner(self, segment: str) -> Owner | None:
        return self._by_name.get(segment)

    def learn(self, owner: Owner) -> None:
        if owner.pk is not None:
            self._drop(owner.pk)
            self._by_name[owner.robot] = owner
            self._names[owner.pk] = owner.robot

    def update(self, pk: int, owner: Owner | None) -> None:
        """Take robot ``pk`` as it is now (None: deleted)."""
        self._drop(pk)
        if owner is not None:
            self.learn(owner)

    def _drop(self, pk: int) -> None:
        name = self._names.pop(pk, None)
        if name is not None:
            self._by_name.pop(name, None)


class Access:
    """One connection's authorisation decisions, cached by name.

    Each check raises NotAllowed naming what was refused. Owners come from the process's
    ``Registry``; this connection remembers only which names no robot owned when it asked,
    and which checks passed. ``reset`` forgets both when access changes. Each cache holds
    at most ``MAX_REMEMBERED`` entries and starts afresh past it, so a client naming ever
    new names costs lookups again, never more memory.
    """

    MAX_REMEMBERED = 4096

    def __init__(self, principal: Principal, registry: Registry | None = None) -> None:
        self.principal = principal
        self.registry = registry or Registry()
        self._unowned: dict[str, None] = {}
        self._names: dict[str, str] = {}
        self._granted: set[tuple[str, str]] = set()
        self._self = (
            Owner(principal.robot, principal.buildings, principal.robot_pk)
            if principal.robot is not None
            else None
        )

    def reset(self) -> None:
        """Forget every decision: owners or grants changed."""
        self._unowned.clear()
        self._names.clear()
        self._granted.clear()

    async def resolve(self, name: str) -> str:
        """Return ``name`` made absolute in this connection's namespace, and placed in its
        realm if no robot owns it. Raises InvalidName."""
        resolved = self._names.get(name)
        if resolved is None:
            absolute = names.absolute(name, self.principal.namespace)
            resolved = absolute
            if (
                not names.is_reserved(absolute)
                and await self._owner_of(rules.owner_segment(absolute)) is None
            ):
                resolved = names.in_realm(self.principal.realm, absolute)
            _room_in(self._names, self.MAX_REMEMBERED)[name] = resolved
        return resolved

    def shown(self, name: str) -> str | None:
        """Return a resolved name as this connection writes it; None for a name of
        another realm, which it must not see."""
        realm = names.realm_of(name)
        if realm is None:
            return name
        return names.outside_realm(name) if realm == self.principal.realm else None

    async def _owner_of(self, segment: str) -> Owner | None:
        if self._self is not None and segment == self._self.robot:
            return self._self
        owner = self.registry.owner(segment)
        if owner is not None or segment in self._unowned:
            return owner
        found: Owner | None = await database_sync_to_async(owner_named)(segment)
        if found is None:
            _room_in(self._unowned, self.MAX_REMEMBERED)[segment] = None
        else:
            self.registry.learn(found)
        return found

    async def owner(self, name: str) -> Owner | None:
        """Return the robot that owns resolved ``name``; None for a realm's name."""
        if names.realm_of(name) is not None:
            return None
        return await self._owner_of(rules.owner_segment(name))

    async def require(self, what: str, name: str) -> None:
        """Check that this connection may do ``what`` to ``name``; raise NotAllowed if not.

        ``what`` is one of ``subscribe``, ``publish``, ``advertise``, ``advertise_service``,
        ``call``, ``see``, ``drive``, ``set_param``.
        """
        if (what, name) in self._granted:
            return
        if not _RULES[what](self.principal, name, await self.owner(name)):
            shown = names.outside_realm(name)
            raise NotAllowed(f"{self.principal.label} may not {what.replace('_', ' ')} {shown}")
        if len(self._granted) >= self.MAX_REMEMBERED:
            self._granted.clear()
        self._granted.add((what, name))

    def granted(self, what: str, name: str) -> bool:
        """True if ``require(what, name)`` already succeeded on this connection."""
        return (what, name) in self._granted

    async def allows(self, what: str, name: str) -> bool:
        """True if ``require(what, name)`` passes, taken afresh."""
        try:
            await self.require(what, name)
        except NotAllowed:
            return False
        return True


def _room_in(cache: dict[str, Any], most: int) -> dict[str, Any]:
    """Return ``cache``, emptied first if it holds ``most`` entries already."""
    if len(cache) >= most:
        cache.clear()
    return cache


def _may_set_param(principal: Principal, name: str, owner: Owner | None) -> bool:
    return rules.may_advertise(principal, name, owner) or rules.may_drive(principal, owner)


_RULES = {
    "subscribe": lambda p, _name, owner: rules.may_subscribe(p, owner),
    "see": lambda p, _name, owner: rules.may_see(p, owner),
    "publish": rules.may_publish,
    "advertise": rules.may_advertise_topic,
    "advertise_service": rules.may_advertise,
    "call": lambda p, _name, owner: rules.may_call(p, owner),
    "drive": lambda p, _name, owner: rules.may_drive(p, owner),
    "set_param": _may_set_param,
}
