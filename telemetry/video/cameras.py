"""Which camera a request names, and whether its principal may watch it (ORM side).

Authentication is the rosbridge server's: a robot token (``?token=`` or ``Authorization:
Token ...``) admits that robot, a session admits a person with their role and buildings.
Then a person may watch the cameras of robots in the buildings they may view (viewer and
up), a robot only its own camera. A camera a person may not see answers as if it did not
exist (404), as the rest of the API does; a robot asking for another robot's camera is
refused outright (403).

A topic is a camera if it belongs to a registered robot (its first segment) and carries
``sensor_msgs/CompressedImage``: the contract's ``/{robot}/camera/image/compressed``
always does; any other topic does while it is published with that type, or as
``foxglove_msgs/CompressedVideo`` (H.264, for WebRTC viewers), on this server process or,
in scaled mode, on another.
"""

from __future__ import annotations

from dataclasses import dataclass

from channels.db import database_sync_to_async
from django.http import HttpRequest

from cloudnav_core import topics
from robots.models import Robot

# The rosbridge server's own identity rules, so a robot or a person is the same principal
# over HTTP as over its WebSocket (their scope-based entry point checks a WebSocket origin).
from telemetry.access.decisions import Identity, owner_named, person_identity, robot_identity
from telemetry.access.rules import Owner, Principal, check_watch, may_watch
from telemetry.domain import names
from telemetry.domain.video import (
    NotAuthenticated,
    UnknownStream,
    camera_topic_candidates,
    is_camera,
)
from telemetry.exceptions import InvalidName
from telemetry.rosbridge.fleet_feed import fleet_type
from telemetry.rosbridge.hub import Hub

CAMERA = "camera/image/compressed"


@dataclass(frozen=True, slots=True)
class Camera:
    """A camera topic (absolute name) and the robot it belongs to."""

    topic: str
    robot: str
    robot_pk: int | None = None


def token_of(request: HttpRequest) -> str | None:
    """Return the robot token of ``?token=`` or ``Authorization: Token ...``, if any."""
    token = request.GET.get("token")
    if token:
        return token
    header = request.headers.get("Authorization", "").split()
    if len(header) == 2 and header[0].lower() == "token":
        return header[1]
    return None


async def principal_of(request: HttpRequest) -> Principal:
    """Return who is asking. A signed-in user without a role is a principal who sees
    nothing. Raises NotAuthenticated without a credential or for an unknown token."""
    token = token_of(request)
    if token is not None:
        identity: Identity | None = await database_sync_to_async(robot_identity)(token)
        if identity is None:
            raise NotAuthenticated("unknown robot token")
        return identity.principal
    user = await request.auser()
    if not user.is_authenticated:
        raise NotAuthenticated("sign in, or give a robot token")
    session = getattr(getattr(request, "session", None), "session_key", None)
    person: Identity | None = await database_sync_to_async(person_identity)(user, session)
    if person is None:
        return Principal(label=f"user:{user.get_username()}", robot=None, buildings=frozenset())
    return person.principal


async def find_camera(hub: Hub, asked: str, principal: Principal) -> Camera:
    """Return the camera ``asked`` names (the topic, or web_video_server's base topic).

    Raises UnknownStream when it names no camera, or one the person may not see;
    NotWatchable when a robot asks for another robot's camera.
    """
    for candidate in camera_topic_candidates(asked):
        try:
            topic = names.absolute(candidate)
        except InvalidName:
            continue
        if await carries_images(hub, topic):
            owner = await database_sync_to_async(owner_named)(names.first_segment(topic))
            if owner is not None:
                check_watch(principal, owner)
                return Camera(topic, owner.robot, owner.pk)
    raise UnknownStream(f"{asked} is not a camera topic")


async def carries_images(hub: Hub, topic: str) -> bool:
    """True if ``topic`` is (or is now published as) a compressed image or video topic."""
    known = fleet_type(topic)
    local = hub.bus.get(topic)
    if known is None and local is not None:
        known = local.type
    if known is None:
        found = await hub.relay.find("topics", topic)
        known = found[1] if found else None
    return known is not None and is_camera(topic, known)


async def published_cameras(hub: Hub) -> set[str]:
    """Return the compressed image and video topics published now, here or on other
    processes."""
    found = {name for name, type_name in hub.bus.published_topics() if is_camera(name, type_name)}
    entries = await hub.relay.entries("topics")
    found |= {n for n, t, _ in entries if t and is_camera(n, t)}
    return found


def visible_robots(principal: Principal) -> list[Owner]:
    """Return the robots whose cameras ``principal`` may watch, by name."""
    robots = Robot.objects.prefetch_related("buildings").order_by("name")
    if principal.robot is not None:
        robots = robots.filter(name=principal.robot)
    else:
        robots = robots.filter(buildings__in=principal.buildings).distinct()
    owners = [Owner(r.name, frozenset(b.pk for b in r.buildings.all())) for r in robots]
    return [owner for owner in owners if may_watch(principal, owner)]


@dataclass(frozen=True, slots=True)
class CameraListing:
    """One entry of the camera page: the camera and whether frames are coming now."""

    camera: Camera
    live: bool


async def watchable_cameras(hub: Hub, principal: Principal) -> list[CameraListing]:
    """Return every camera ``principal`` may watch: each robot's contract camera, and any
    other compressed image topic one of those robots publishes now."""
    owners = await database_sync_to_async(visible_robots)(principal)
    published = await published_cameras(hub)
    listing = []
    for owner in owners:
        default = topics.robot_topic(owner.robot, CAMERA)
        extra = sorted(t for t in published if names.first_segment(t) == owner.robot)
        for topic in [default, *(t for t in extra if t != default)]:
            listing.append(CameraListing(Camera(topic, owner.robot), topic in published))
    return listing
