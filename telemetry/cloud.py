"""The cloud's own services under ``/cloudnav``: teleop lock, route planning, tag resolution,
path planning, visual relocalisation."""

from __future__ import annotations

import asyncio
import math
from concurrent.futures import ThreadPoolExecutor
from typing import Any

from channels.db import database_sync_to_async
from django.conf import settings
from django.db import close_old_connections

from maps import services as map_services
from maps.domain.planning import DEFAULT_ROBOT_RADIUS, PlanningError, path_length, plan_on
from maps.domain.tagpayload import parse_payload
from maps.exceptions import KeyframeError, MapStoreError
from maps.visual.service import relocalise_in
from telemetry.domain import names
from telemetry.domain.messages import Path, path_of
from telemetry.domain.protocol import Json
from telemetry.domain.times import now_stamp
from telemetry.exceptions import NotAllowed, ServiceFailed
from telemetry.server_services import ServerService, ServiceCall

TELEOP_LOCK = f"{names.CLOUDNAV}/teleop_lock"
ROUTE = f"{names.CLOUDNAV}/route"
RESOLVE_TAG = f"{names.CLOUDNAV}/resolve_tag"
PLAN_PATH = f"{names.CLOUDNAV}/plan_path"
RELOCALISE = f"{names.CLOUDNAV}/relocalise"


def _text(call: ServiceCall, key: str) -> str:
    value = call.arg(key)
    if not isinstance(value, str) or not value.strip():
        raise ServiceFailed(f"'{key}' is required")
    return value.strip()


async def teleop_lock(call: ServiceCall) -> Json:
    """``{robot, action: acquire|release|status}`` -> ``{success, holder, message}``.

    Only someone who may drive the robot may take its lock; one connection holds it at a
    time, until it releases it, disconnects, or sends no ``cmd_vel`` for the lock's TTL
    (``CLOUDNAV_TELEOP_LOCK_TTL``, 5 s). ``status`` tells anyone who may see the robot who
    holds it ("" for nobody). Raises ServiceFailed if ``robot`` is not a robot's name.
    """
    robot, action = call.arg("robot"), call.arg("action", "acquire")
    if not names.is_robot_name(robot):
        raise ServiceFailed("'robot' must be a robot's name (a letter, then letters, digits or _)")
    locks, conn = call.server.teleop, call.conn
    if action == "status":
        await call.access.require("see", names.robot_topic(robot, names.CMD_VEL))
        return {"success": True, "holder": await locks.holder(robot), "message": ""}
    await call.access.require("drive", names.robot_topic(robot, names.CMD_VEL))
    if action == "acquire":
        granted, holder = await locks.acquire(robot, conn.key, conn.principal.label)
        message = "" if granted else f"{robot} is driven by {holder}"
        return {"success": granted, "holder": holder, "message": message}
    if action == "release":
        released = await locks.release(robot, conn.key)
        message = "" if released else f"this connection does not hold the lock of {robot}"
        return {"success": released, "holder": "", "message": message}
    raise ServiceFailed("'action' must be 'acquire', 'release' or 'status'")


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
    building = map_services.visible_building(visible, code)
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
    submap = map_services.visible_submap(visible, building, code)
    if submap is None:
        return None
    return {"map_id": submap.map_id, "building": building, "map": code, "version": submap.version}


async def plan_path(call: ServiceCall) -> Json:
    """``{map_id, start: {x, y}, goal: {x, y}, robot_radius?}`` -> ``{path, length}``.

    The robot agent's global planner, run in the cloud (``maps.domain.planning``: the
    sub-map's grid inflated by ``robot_radius``, A*, line-of-sight shortcut): ``path`` is
    a ``nav_msgs/Path`` in the sub-map's frame (``frame_id`` = its Map ID), ``length`` in
    metres. Planning errors (outside the map, in an obstacle, no path) fail the call.
    """
    building, _, code = _text(call, "map_id").partition("/")
    start, goal = _point(call, "start"), _point(call, "goal")
    radius = call.arg("robot_radius", DEFAULT_ROBOT_RADIUS)
    if not isinstance(radius, int | float) or not 0 <= radius < 5:
        raise ServiceFailed("'robot_radius' must be a number of metres in [0, 5)")
    return await database_sync_to_async(_plan)(
        call.conn.principal.buildings, building, code, start, goal, float(radius)
    )


def _point(call: ServiceCall, key: str) -> tuple[float, float]:
    value = call.arg(key)
    try:
        point = float(value["x"]), float(value["y"])
    except (KeyError, TypeError, ValueError):
        raise ServiceFailed(f"'{key}' must be {{x, y}}") from None
    if not all(math.isfinite(v) for v in point):
        raise ServiceFailed(f"'{key}' must be finite")
    return point


def _plan(
    visible: frozenset[int],
    building: str,
    code: str,
    start: tuple[float, float],
    goal: tuple[float, float],
    radius: float,
) -> dict[str, Any]:
    submap = map_services.visible_submap(visible, building, code)
    if submap is None:
        raise ServiceFailed(f"{building}/{code} is not a visible sub-map")
    try:
        points = plan_on(map_services.costmap_of(submap, radius), start, goal)
    except PlanningError as exc:
        raise ServiceFailed(str(exc)) from None
    return {"path": _path(submap.map_id, points), "length": path_length(points)}


def _path(frame_id: str, points: list[tuple[float, float]]) -> Path:
    """A ``nav_msgs/Path`` through ``points`` (headings left at identity), stamped now in
    both time spellings."""
    return path_of(frame_id, [(x, y, 0.0) for x, y in points], now_stamp())


async def relocalise(call: ServiceCall) -> Json:
    """``{images, depth?, camera_info?, mount?, building?, submap?}`` -> ``{localised,
    map_id, pose: {x, y, yaw}, covariance (9), inliers, keyframes, image, reason}``.

    Searched among the keyframes of the caller's buildings (``building`` narrows it; one
    it may not use is refused). Runs on the relocalisation threads
    (``CLOUDNAV_RELOCALISE_WORKERS``), never on the event loop that relays topics.
    """
    args = call.args[0] if isinstance(call.args, list) and call.args else call.args
    if not isinstance(args, dict):
        raise ServiceFailed("the request must be an object")
    code = args.get("building")
    if code is not None and not isinstance(code, str):
        raise ServiceFailed("'building' must be a building code")
    visible = call.conn.principal.buildings
    try:
        return await _on_relocalise_threads(_relocalise, visible, code, args)
    except KeyframeError as exc:
        raise ServiceFailed(str(exc)) from None


def _relocalise(visible: frozenset[int], code: str | None, args: dict[str, Any]) -> Json:
    try:
        buildings = map_services.visible_buildings(visible)
        if code:
            buildings = [b for b in buildings if b.code == code]
            if not buildings:
                raise NotAllowed(f"building {code} does not exist or is not visible")
        return relocalise_in(buildings, args)
    finally:
        close_old_connections()


_RELOCALISE_POOL: ThreadPoolExecutor | None = None


async def _on_relocalise_threads(function: Any, *args: Any) -> Any:
    global _RELOCALISE_POOL
    if _RELOCALISE_POOL is None:
        workers = max(1, settings.CLOUDNAV_RELOCALISE_WORKERS)
        _RELOCALISE_POOL = ThreadPoolExecutor(workers, thread_name_prefix="relocalise")
    return await asyncio.get_running_loop().run_in_executor(_RELOCALISE_POOL, function, *args)


def services() -> dict[str, ServerService]:
    return {
        TELEOP_LOCK: ServerService("cloudnav/TeleopLock", teleop_lock),
        ROUTE: ServerService("cloudnav/Route", route),
        RESOLVE_TAG: ServerService("cloudnav/ResolveTag", resolve_tag),
        PLAN_PATH: ServerService("cloudnav/PlanPath", plan_path),
        RELOCALISE: ServerService("cloudnav/Relocalise", relocalise),
    }
