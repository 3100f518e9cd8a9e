"""The cloud's own services under ``/cloudnav``: teleop lock, route planning, tag resolution,
path planning, visual relocalisation."""

from __future__ import annotations

import asyncio
import math
from typing import TYPE_CHECKING, Any

from channels.db import database_sync_to_async
from django.contrib.auth import get_user_model

from cloudnav_core import topics
from cloudnav_core.messages import Path, path_of
from cloudnav_core.times import now_stamp
from maps import services as map_services
from maps.access import Role, role_in
from maps.domain.planning import DEFAULT_ROBOT_RADIUS, PlanningError, path_length, plan_on
from maps.domain.tagpayload import parse_payload
from maps.exceptions import KeyframeError, MapStoreError, RelocalisationRefused
from maps.models import Building
from maps.visual.lanes import Caller, RelocalisationBusy
from maps.visual.service import buildings_to_search, relocalise_queued
from telemetry.domain import names
from telemetry.domain.protocol import Json
from telemetry.exceptions import NotAllowed, PoseRefused, ServiceFailed
from telemetry.rosbridge.server_services import ServerService, ServiceCall

if TYPE_CHECKING:
    from telemetry.rosbridge.teleop_locks import TeleopLocks

TELEOP_LOCK = f"{topics.CLOUDNAV}/teleop_lock"
ROUTE = f"{topics.CLOUDNAV}/route"
RESOLVE_TAG = f"{topics.CLOUDNAV}/resolve_tag"
PLAN_PATH = f"{topics.CLOUDNAV}/plan_path"
RELOCALISE = f"{topics.CLOUDNAV}/relocalise"
STOP = f"{topics.CLOUDNAV}/stop"
CHECK_POSE = f"{topics.CLOUDNAV}/check_pose"


def _text(call: ServiceCall, key: str) -> str:
    value = call.arg(key)
    if not isinstance(value, str) or not value.strip():
        raise ServiceFailed(f"'{key}' is required")
    return value.strip()


async def teleop_lock(call: ServiceCall) -> Json:
    """``{robot, action: acquire|release|status|ask|refuse|take}`` -> ``{success, holder,
    message}``.

    Only someone who may drive the robot may take its lock; one connection holds it at a
    time, until it releases it, disconnects, or sends no ``cmd_vel`` for the lock's TTL
    (``CLOUDNAV_TELEOP_LOCK_TTL``, 5 s): asking again renews nothing, and a connection
    whose lock lapsed waits that long before it may take it again. ``status`` tells anyone
    who may see the robot who holds it ("" for nobody) and, while someone asks for it, who
    (``asked_by``) and in how many seconds it passes to them (``handover_in``). ``ask``
    asks the holder: the lock passes to the asker ``CLOUDNAV_TELEOP_HANDOVER`` (5 s) later,
    when they ask again, unless the holder ``refuse``-s first. ``take`` (an admin of one
    of the robot's buildings) takes the lock from whoever holds it. Raises ServiceFailed
    if ``robot`` is not a robot's name.
    """
    robot, action = call.arg("robot"), call.arg("action", "acquire")
    if not names.is_robot_name(robot):
        raise ServiceFailed("'robot' must be a robot's name (a letter, then letters, digits or _)")
    locks, conn = call.server.teleop, call.conn
    if action == "status":
        await call.access.require("see", topics.robot_topic(robot, topics.CMD_VEL))
        return await _status(locks, robot)
    await call.access.require("drive", topics.robot_topic(robot, topics.CMD_VEL))
    if action == "acquire":
        granted, holder = await locks.acquire(robot, conn.key, conn.principal.label)
        message = "" if granted else f"{robot} is driven by {holder}"
        if not granted and not holder:
            message = f"your control of {robot} lapsed: others may take it before you again"
        return {"success": granted, "holder": holder, "message": message}
    if action == "ask":
        granted, holder, message, left = await locks.ask(robot, conn.key, conn.principal.label)
        answer: dict[str, Json] = {"success": granted, "holder": holder, "message": message}
        if left is not None:
            answer["handover_in"] = round(left, 1)  # waiting: ask again then
        return answer
    if action == "refuse":
        asker = await locks.refuse(robot, conn.key)
        message = f"{asker} was refused" if asker else "nobody asks for the lock you hold"
        return {"success": bool(asker), "holder": await locks.holder(robot), "message": message}
    if action == "take":
        if not await database_sync_to_async(_admin_of)(conn.principal.user_id, robot):
            raise NotAllowed(f"only an admin of {robot}'s building may take its teleop lock")
        granted, taken_from = await locks.take(robot, conn.key, conn.principal.label)
        message = f"taken from {taken_from}" if taken_from else ""
        return {"success": granted, "holder": conn.principal.label, "message": message}
    if action == "release":
        released = await locks.release(robot, conn.key)
        message = "" if released else f"this connection does not hold the lock of {robot}"
        return {"success": released, "holder": "", "message": message}
    raise ServiceFailed(
        "'action' must be 'acquire', 'release', 'status', 'ask', 'refuse' or 'take'"
    )


async def _status(locks: TeleopLocks, robot: str) -> dict[str, Json]:
    """Who holds the lock; while someone asks for it, who and in how many seconds it
    passes to them (``asked_by``, ``handover_in``)."""
    answer: dict[str, Json] = {"success": True, "holder": await locks.holder(robot), "message": ""}
    asked = await locks.request(robot) if answer["holder"] else None
    if asked is not None:
        answer["asked_by"], answer["handover_in"] = asked[0], round(asked[1], 1)
    return answer


def _admin_of(user_id: int | None, robot: str) -> bool:
    """True if user ``user_id`` is an admin of a building of ``robot``."""
    if user_id is None:
        return False
    user = get_user_model().objects.filter(pk=user_id, is_active=True).first()
    buildings = Building.objects.filter(robots__name=robot)
    return user is not None and any(role_in(user, b) >= Role.ADMIN for b in buildings)


async def stop(call: ServiceCall) -> Json:
    """``{robot}`` -> ``{success, message, goal, missions, teleop}``: STOP (``telemetry.stop``).

    Whoever may drive the robot may stop it: its teleop lock is withdrawn, it gets a zero
    Twist, its active goal is cancelled whoever sent it, its running missions are paused,
    and a ``robot_stopped`` event names who stopped it. ``goal`` is what the robot said
    of its goal, ``missions`` the missions paused, ``teleop`` whose lock was withdrawn.
    Raises ServiceFailed if ``robot`` is not a robot's name.
    """
    robot = call.arg("robot")
    if not names.is_robot_name(robot):
        raise ServiceFailed("'robot' must be a robot's name (a letter, then letters, digits or _)")
    await call.access.require("drive", topics.robot_topic(robot, topics.CMD_VEL))
    stopped = await call.server.stop.stop(robot, call.conn)
    return stopped.as_values()


async def check_pose(call: ServiceCall) -> Json:
    """``{map_id, x, y, what?: goal|initial pose, robot?}`` -> ``{success, message}``:
    whether a robot could stand there (``telemetry.pose_checks``), the reason when not.
    With ``robot``, a goal is also placed among the spots the other robots hold by the
    building's fleet rule: refused with the reason, or moved (then ``message`` says so
    and ``x``, ``y`` are where it goes). The pages ask before sending a goal or an
    initial pose; a publication that fails the same check is refused (or moved) anyway.
    Raises ServiceFailed for a sub-map the caller cannot see or a robot they cannot.
    """
    map_id = _text(call, "map_id").split("@", 1)[0]
    point = _point_of(call.args[0] if isinstance(call.args, list) and call.args else call.args)
    what, robot = call.arg("what", "goal"), call.arg("robot", "")
    if what not in ("goal", "initial pose"):
        raise ServiceFailed("'what' must be 'goal' or 'initial pose'")
    if robot and not names.is_robot_name(robot):
        raise ServiceFailed("'robot' must be a robot's name (a letter, then letters, digits or _)")
    building, _, code = map_id.partition("/")
    visible = await database_sync_to_async(map_services.visible_submap)(
        call.conn.principal.buildings, building, code
    )
    if visible is None:
        raise ServiceFailed(f"{map_id} is not a visible sub-map")
    try:
        if not robot or what != "goal":
            await call.server.poses.check_point(map_id, point, str(what))
            return {"success": True, "message": ""}
        await call.access.require("see", topics.robot_topic(robot, topics.GOAL))
        placed = await call.server.poses.place(map_id, point, robot)
    except PoseRefused as refused:
        return {"success": False, "message": refused.message}
    if placed.refusal:
        return {"success": False, "message": f"{placed.refusal} ({map_id})"}
    if placed.moved_from is None:
        return {"success": True, "message": ""}
    x, y = placed.point
    return {"success": True, "message": placed.message, "x": x, "y": y}


def _point_of(args: Json) -> tuple[float, float]:
    try:
        point = float(args["x"]), float(args["y"])
    except (KeyError, TypeError, ValueError):
        raise ServiceFailed("'x' and 'y' must be numbers") from None
    if not all(math.isfinite(v) for v in point):
        raise ServiceFailed("'x' and 'y' must be finite")
    return point


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
    """``{payload}`` (a tag's QR text) -> ``{map_id, building, map, version}`` (``version``:
    the number of the sub-map's current version, ``v<n>`` to people)."""
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
    return {"map_id": submap.map_id, "building": building, "map": code, "version": submap.revision}


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

    Searched among the keyframes of the buildings the caller may relocalise in (a robot:
    its own; a person: where they may drive; viewers may not), ``building`` narrowing it.
    Runs on the relocalisation lanes ``POST /api/relocalise`` shares (robots first),
    never on the event loop that relays topics; refused when they are full.
    """
    args = call.args[0] if isinstance(call.args, list) and call.args else call.args
    if not isinstance(args, dict):
        raise ServiceFailed("the request must be an object")
    code = args.get("building")
    if code is not None and not isinstance(code, str):
        raise ServiceFailed("'building' must be a building code")
    principal = call.conn.principal
    allowed = principal.buildings if principal.robot else principal.drive_buildings
    caller = Caller(principal.label, robot=principal.robot is not None)
    try:
        buildings = await database_sync_to_async(buildings_to_search)(allowed, code)
        return await asyncio.wrap_future(relocalise_queued(caller, buildings, args))
    except RelocalisationRefused as exc:
        raise NotAllowed(str(exc)) from None
    except (KeyframeError, RelocalisationBusy) as exc:
        raise ServiceFailed(str(exc)) from None


def services() -> dict[str, ServerService]:
    return {
        TELEOP_LOCK: ServerService("cloudnav/TeleopLock", teleop_lock),
        STOP: ServerService("cloudnav/Stop", stop),
        CHECK_POSE: ServerService("cloudnav/CheckPose", check_pose),
        ROUTE: ServerService("cloudnav/Route", route),
        RESOLVE_TAG: ServerService("cloudnav/ResolveTag", resolve_tag),
        PLAN_PATH: ServerService("cloudnav/PlanPath", plan_path),
        RELOCALISE: ServerService("cloudnav/Relocalise", relocalise),
    }
