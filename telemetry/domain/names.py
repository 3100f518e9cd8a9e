"""ROS names, the fleet's names and the channel-layer group names, built here only (a
robot's own topics and services are ``cloudnav_core.topics``).

A name is normalised to its absolute form (``rosapi/topics`` is ``/rosapi/topics``); a robot
connection's relative names resolve into its namespace ``/{robot}/...``, except the global
service namespaces (``rosapi``, ``cloudnav``), which every client calls by relative name.
"""

from __future__ import annotations

import re
from typing import TypeGuard

from cloudnav_core.topics import GLOBAL_NAMESPACES
from telemetry.exceptions import InvalidName

# One token of a ROS 2 name: a letter or underscore, then letters, digits, underscores.
_NAME = re.compile(r"/?[A-Za-z_][A-Za-z0-9_]*(/[A-Za-z_][A-Za-z0-9_]*)*/?")
MAX_NAME_LENGTH = 256
# A robot's name: one such token (as ``robots.models.Robot.name`` holds it).
_SEGMENT = re.compile(r"[A-Za-z_][A-Za-z0-9_]{0,63}")


def absolute(name: str, namespace: str = "") -> str:
    """Return ``name`` as an absolute ROS name, resolving a relative one into ``namespace``.

    Raises InvalidName for anything that is not a ROS name (including ``~`` private names).
    """
    if not isinstance(name, str) or len(name) > MAX_NAME_LENGTH or not _NAME.fullmatch(name):
        raise InvalidName(f"'{name}' is not a valid ROS name")
    name = name.rstrip("/")
    if name.startswith("/"):
        return name
    if namespace and name.split("/", 1)[0] not in GLOBAL_NAMESPACES:
        return f"{namespace}/{name}"
    return "/" + name


def is_robot_name(text: object) -> TypeGuard[str]:
    """True if ``text`` can be a robot's name: one ROS name token of at most 64 characters."""
    return isinstance(text, str) and _SEGMENT.fullmatch(text) is not None


# Names no robot owns live in a realm: one building's (``-b{pk}``), or ``NO_BUILDING`` for
# connections of no building (no tenant's). A realm is a first segment no client can write
# (ROS tokens never start with '-'), which channel-layer groups and Redis keys accept.
REALM_MARK = "-"
NO_BUILDING = REALM_MARK + "none"


def building_realm(pk: int) -> str:
    return f"{REALM_MARK}b{pk}"


def in_realm(realm: str, name: str) -> str:
    """Return ``name`` (absolute) as it lives in ``realm``: ``/-b3/announcements``."""
    return f"/{realm}{name}"


def realm_of(name: str) -> str | None:
    """Return the realm of a name made by ``in_realm``, None for any other name."""
    segment = first_segment(name)
    return segment if segment.startswith(REALM_MARK) else None


def outside_realm(name: str) -> str:
    """Return a realm's name as its clients write it (``/-b3/a`` -> ``/a``)."""
    realm = realm_of(name)
    return name[len(realm) + 1 :] if realm is not None else name


_REALMS = re.compile(r"/" + re.escape(REALM_MARK) + r"[a-z0-9]+(?=/)")


def without_realms(text: str) -> str:
    """Return ``text`` (an error message) with every name in it as its client writes it."""
    return _REALMS.sub("", text)


def robot_namespace(robot: str) -> str:
    return "/" + robot


def first_segment(name: str) -> str:
    """Return the first segment of an absolute name: ``/r1/pose`` -> ``r1``."""
    return name[1:].split("/", 1)[0]


def suffix_in(name: str, namespace_segment: str) -> str | None:
    """Return what follows ``/{namespace_segment}/`` in ``name``, or None outside it."""
    prefix = f"/{namespace_segment}/"
    return name[len(prefix) :] if name.startswith(prefix) else None


def is_reserved(name: str) -> bool:
    """True for names in the server's own service namespaces, which no client may advertise."""
    return first_segment(name) in GLOBAL_NAMESPACES


def canonical_type(type_name: str) -> str:
    """Return a message type in the ROS 1 spelling so ``pkg/msg/T`` and ``pkg/T`` compare equal."""
    parts = type_name.strip().split("/")
    if len(parts) == 3 and parts[1] in {"msg", "srv", "action"}:
        return f"{parts[0]}/{parts[2]}"
    return type_name.strip()


PROCESS_CHANNEL_PREFIX = "rb.process"
REDIS_KEY_PREFIX = "cloudnav:rb:"


def redis_key(*parts: str) -> str:
    """Return the key of one piece of shared rosbridge state in Redis (scaled mode)."""
    return REDIS_KEY_PREFIX + ":".join(parts)


def topic_channel(topic: str, database: int = 0) -> str:
    """Return the Redis pub/sub channel that carries ``topic`` between the server processes
    on Redis database ``database`` (Redis shares channels across databases: deployments or
    test runs on one server must not hear each other's)."""
    return f"{REDIS_KEY_PREFIX}{database}:topic:{topic}"


def topic_of_channel(channel: str) -> str:
    """Return the topic a ``topic_channel`` carries."""
    return channel.partition(":topic:")[2]
