"""Who is connecting, and what each name's owner allows them: the ORM side of the rosbridge.

``authenticate`` runs once per connection; ``Access`` keeps one connection's decisions,
so after the first frame on a name no frame on it touches the database again.
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
from robots.authentication import RobotPrincipal
from robots.models import Robot
from robots.services import robot_for_token
from telemetry.domain import names, rules
from telemetry.domain.rules import Owner, Principal
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
    if token is not None:
        robot: Identity | None = await database_sync_to_async(robot_identity)(token)
        return robot
    user = scope.get("user")
    if user is None or not user.is_authenticated or not origin_allowed(scope):
        return None
    person: Identity | None = await database_sync_to_async(person_identity)(user)
    return person


def robot_identity(token: str) -> Identity | None:
    robot = robot_for_token(token)
    if robot is None:
        return None
    buildings = frozenset(b.pk for b in buildings_for(RobotPrincipal(robot)))
    principal = Principal(label=f"robot:{robot.name}", robot=robot.name, buildings=buildings)
    return Identity(principal=principal, robot_pk=robot.pk)


def person_identity(user: Any) -> Identity | None:
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
    )
    return Identity(principal=principal)


def owner_named(segment: str) -> Owner | None:
    """Return the robot called ``segment`` with its buildings, or None if there is none."""
    robot = Robot.objects.filter(name=segment).first()
    if robot is None:
        return None
    return Owner(robot.name, frozenset(robot.buildings.values_list("pk", flat=True)))


class Access:
    """One connection's authorisation decisions, cached by name.

    Each check raises NotAllowed naming what was refused. Robot memberships are read once
    per connection: a change made while it is open applies when it reconnects. Each cache
    holds at most ``MAX_REMEMBERED`` entries and starts afresh past it, so a client naming
    ever new names costs lookups again, never more memory.
    """

    MAX_REMEMBERED = 4096

    def __init__(self, principal: Principal) -> None:
        self.principal = principal
        self._owners: dict[str, Owner | None] = {}
        self._names: dict[str, str] = {}
        self._granted: set[tuple[str, str]] = set()
        if principal.robot is not None:
            self._owners[principal.robot] = Owner(principal.robot, principal.buildings)

    def resolve(self, name: str) -> str:
        """Return ``name`` made absolute in this connection's namespace. Raises InvalidName."""
        resolved = self._names.get(name)
        if resolved is None:
            resolved = names.absolute(name, self.principal.namespace)
            _room_in(self._names, self.MAX_REMEMBERED)[name] = resolved
        return resolved

    async def owner(self, name: str) -> Owner | None:
        segment = rules.owner_segment(name)
        if segment not in self._owners:
            found = await database_sync_to_async(owner_named)(segment)
            _room_in(self._owners, self.MAX_REMEMBERED)[segment] = found
        return self._owners[segment]

    async def require(self, what: str, name: str) -> None:
        """Check that this connection may do ``what`` to ``name``; raise NotAllowed if not.

        ``what`` is one of ``subscribe``, ``publish``, ``advertise``, ``advertise_service``,
        ``call``, ``see``, ``drive``, ``set_param``.
        """
        if (what, name) in self._granted:
            return
        if not _RULES[what](self.principal, name, await self.owner(name)):
            raise NotAllowed(f"{self.principal.label} may not {what.replace('_', ' ')} {name}")
        if len(self._granted) >= self.MAX_REMEMBERED:
            self._granted.clear()
        self._granted.add((what, name))

    def granted(self, what: str, name: str) -> bool:
        """True if ``require(what, name)`` already succeeded on this connection."""
        return (what, name) in self._granted


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
