"""Fleet rules: who may subscribe, publish, call and advertise which names.

A name whose first segment is a registered robot belongs to that robot (``/r1/pose``);
a name no robot owns lives in one building's realm (``names.in_realm``): each connection
reads and writes such names in its own realm only, so tenants share none. The rules:

- a robot may publish, advertise and serve only inside its own namespace, and may
  subscribe to its own names, to robots sharing one of its buildings, and to shared names;
- people see the robots of the buildings they are members of (viewer and up); operators
  and admins may publish a robot's command topics and call its services and actions;
  viewers publish nothing;
- only admins publish or advertise shared names; nobody advertises in ``/rosapi`` or
  ``/cloudnav``, the server's own.
"""

from __future__ import annotations

from dataclasses import dataclass

from cloudnav_core.topics import COMMAND_TOPICS, SERVER_TOPICS
from telemetry.domain.names import first_segment, is_reserved, suffix_in
from telemetry.domain.video import NotWatchable, UnknownStream


@dataclass(frozen=True, slots=True)
class Principal:
    """Who is on a connection, taken once when it opens.

    ``realm`` is where the names no robot owns live for this connection (one of its
    buildings); ``user_id``, ``robot_pk`` and ``credential`` (a robot's token digest, a
    person's session key) say what it depends on, so a revocation finds it."""

    label: str
    robot: str | None
    buildings: frozenset[int]
    drive_buildings: frozenset[int] = frozenset()
    admin: bool = False
    realm: str = ""
    user_id: int | None = None
    robot_pk: int | None = None
    credential: str | None = None

    @property
    def namespace(self) -> str:
        return f"/{self.robot}" if self.robot else ""


@dataclass(frozen=True, slots=True)
class Owner:
    """The robot a name belongs to, and that robot's buildings (and key, when known)."""

    robot: str
    buildings: frozenset[int]
    pk: int | None = None


def owner_segment(name: str) -> str:
    """Return the segment of ``name`` that may name its robot."""
    return first_segment(name)


def may_see(principal: Principal, owner: Owner | None) -> bool:
    if owner is None or owner.robot == principal.robot:
        return True
    return bool(owner.buildings & principal.buildings)


def may_drive(principal: Principal, owner: Owner | None) -> bool:
    """True if ``principal`` is a person who may command the robot ``owner``."""
    if owner is None or principal.robot is not None:
        return False
    return bool(owner.buildings & principal.drive_buildings)


def may_subscribe(principal: Principal, owner: Owner | None) -> bool:
    return may_see(principal, owner)


def may_publish(principal: Principal, name: str, owner: Owner | None) -> bool:
    if principal.robot is not None:
        return (
            owner is not None
            and owner.robot == principal.robot
            and suffix_in(name, owner.robot) not in SERVER_TOPICS
        )
    if owner is None:
        return principal.admin and not is_reserved(name)
    return suffix_in(name, owner.robot) in COMMAND_TOPICS and may_drive(principal, owner)


def may_advertise(principal: Principal, name: str, owner: Owner | None) -> bool:
    """Rule for advertising a topic, a service or an action under ``name``."""
    if is_reserved(name):
        return False
    if principal.robot is not None:
        return owner is not None and owner.robot == principal.robot
    if owner is None:
        return principal.admin
    return False


def may_advertise_topic(principal: Principal, name: str, owner: Owner | None) -> bool:
    """Advertising a topic is announcing a publication: operators may announce commands."""
    return may_advertise(principal, name, owner) or may_publish(principal, name, owner)


def may_call(principal: Principal, owner: Owner | None) -> bool:
    """Rule for calling a client's service or sending a goal to a client's action."""
    if owner is None:
        return True
    if principal.robot is not None:
        return owner.robot == principal.robot
    return may_drive(principal, owner)


# ------------------------------------------------------------ cameras


def check_watch(principal: Principal, owner: Owner) -> None:
    """Raise unless ``principal`` may watch the cameras of robot ``owner`` (a robot only its
    own; a person those of robots it may see)."""
    if principal.robot is not None:
        if principal.robot != owner.robot:
            raise NotWatchable(f"robot {principal.robot} may only watch its own camera")
    elif not may_see(principal, owner):
        raise UnknownStream(f"no camera of {owner.robot} is visible to {principal.label}")


def may_watch(principal: Principal, owner: Owner | None) -> bool:
    if owner is None:
        return False
    try:
        check_watch(principal, owner)
    except (UnknownStream, NotWatchable):
        return False
    return True
