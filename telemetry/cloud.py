"""The cloud's own services under ``/cloudnav``: teleop lock, route planning, tag resolution."""

from __future__ import annotations

from typing import Any

from channels.db import database_sync_to_async

from maps import services as map_services
from maps.domain.tagpayload import parse_payload
from maps.exceptions import MapStoreError
from maps.models import Building, SubMap
from telemetry.domain import names
from telemetry.domain.protocol import Json
from telemetry.exceptions import NotAllowed, ServiceFailed
from telemetry.server_services import ServerService, ServiceCall

TELEOP_LOCK = f"{names.CLOUDNAV}/teleop_lock"
ROUTE = f"{names.CLOUDNAV}/route"
RESOLVE_TAG = f"{names.CLOUDNAV}/resolve_tag"


def _text(call: ServiceCall, key: str) -> str:
    value = call.arg(key)
    if not isinstance(value, str) or not value.strip():
        raise ServiceFailed(f"'{key}' is required")
    return value.strip()


async def teleop_lock(call: ServiceCall) -> Json:
    """``{robot, action: acquire|release}`` -> ``{success, holder, message}``.

    Only someone who may drive the robot may take its lock; one connection holds it at a
    time, until it releases it, disconnects, or sends no ``cmd_vel`` for the lock's TTL.
    """
    robot, action = _text(call, "robot"), call.arg("action", "acquire")
    await call.access.require("drive", names.robot_topic(robot, names.CMD_VEL))
    locks, conn = call.hub.teleop, call.conn
    if action == "acquire":
        granted, holder = await locks.acquire(robot, conn.key, conn.principal.label)
        message = "" if granted else f"{robot} is driven by {holder}"
        return {"success": granted, "holder": holder, "message": message}
    if action == "release":
        released = await locks.release(robot, conn.key)
        message = "" if released else f"this connection does not hold the lock of {robot}"
        return {"success": released, "holder": "", "message": message}
    raise ServiceFailed("'action' must be 'acquire' or 'release'")


async def route(call: ServiceCall) -> Json:
    """``{building, from, to}`` -> ``{steps: [{map, map_id, tag}]}``, ``tag`` a marker id or -1."""
    code = _text(call, "building")
    start, goal = _text(call, "from"), _text(call, "to")
    try:
        return await database_sync_to_async(_route)(
            call.conn.principal.buildings, code, start, goal
        )
    except MapStoreError as exc:
        raise ServiceFailed(str(exc)) from None


def _route(visible: frozenset[int], code: str, start: str, goal: str) -> dict[str, Any]:
    building = Building.objects.filter(code=code, pk__in=visible).first()
    if building is None:
        raise NotAllowed(f"building {code} does not exist or is not visible")
    steps = map_services.route_in(building, start, goal)
    return {
        "steps": [
            {
                "map": step.submap,
                "map_id": f"{building.code}/{step.submap}",
                "tag": step.tag.marker_id if step.tag else -1,
            }
            for step in steps
        ]
    }


async def resolve_tag(call: ServiceCall) -> Json:
    """``{payload}`` (a tag's QR text) -> ``{map_id, building, map, version}``."""
    try:
        payload = parse_payload(_text(call, "payload"))
    except MapStoreError as exc:
        raise ServiceFailed(str(exc)) from None
    found = await database_sync_to_async(_submap)(
        call.conn.principal.buildings, payload.building_code, payload.map_code
    )
    if found is None:
        raise ServiceFailed(f"{payload.building_code}/{payload.map_code} is not a visible sub-map")
    return found


def _submap(visible: frozenset[int], building: str, code: str) -> dict[str, Any] | None:
    submap = (
        SubMap.objects.filter(building__code=building, building__pk__in=visible, code=code)
        .select_related("building")
        .first()
    )
    if submap is None:
        return None
    return {"map_id": submap.map_id, "building": building, "map": code, "version": submap.version}


def services() -> dict[str, ServerService]:
    return {
        TELEOP_LOCK: ServerService("cloudnav/TeleopLock", teleop_lock),
        ROUTE: ServerService("cloudnav/Route", route),
        RESOLVE_TAG: ServerService("cloudnav/ResolveTag", resolve_tag),
    }
