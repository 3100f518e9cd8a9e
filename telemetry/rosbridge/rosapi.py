"""The rosapi services a dashboard calls, answering as rosapi does.

Listings show only what the caller may see: a robot's topics, services and parameters are
visible to those who may see that robot. ``get_time`` answers in both time spellings.
"""

from __future__ import annotations

import json
from collections.abc import Iterable

from cloudnav_core.times import now_stamp
from cloudnav_core.topics import ROSAPI
from telemetry.access.decisions import Access
from telemetry.domain import names
from telemetry.domain.names import canonical_type
from telemetry.domain.protocol import Json
from telemetry.exceptions import NotAllowed, ServiceFailed
from telemetry.rosbridge.server_services import ServerService, ServiceCall

SERVER_NODE = "/cloudnav"


async def _visible(access: Access, items: Iterable[tuple[str, str]]) -> list[tuple[str, str]]:
    """The items the caller may see, named as it writes them: a robot's if it may see the
    robot, a realm's only in its own realm (``Access.shown``)."""
    shown = []
    for name, type_name in sorted(set(items)):
        spelled = access.shown(name)
        if spelled is None:
            continue
        try:
            await access.require("see", name)
        except NotAllowed:
            continue
        shown.append((spelled, type_name))
    return sorted(shown)


async def _topics(call: ServiceCall) -> list[tuple[str, str]]:
    return await _visible(call.access, await call.server.directory.topics())


async def topics(call: ServiceCall) -> Json:
    listed = await _topics(call)
    return {"topics": [n for n, _ in listed], "types": [t for _, t in listed]}


async def topic_type(call: ServiceCall) -> Json:
    wanted = call.access.shown(await _name(call, "topic"))
    return {"type": next((t for n, t in await _topics(call) if n == wanted), "")}


async def topics_for_type(call: ServiceCall) -> Json:
    wanted = canonical_type(str(call.arg("type", "")))
    return {"topics": [n for n, t in await _topics(call) if canonical_type(t) == wanted]}


async def _services(call: ServiceCall) -> list[tuple[str, str]]:
    return await _visible(call.access, await call.server.directory.services())


async def list_services(call: ServiceCall) -> Json:
    return {"services": [n for n, _ in await _services(call)]}


async def service_type(call: ServiceCall) -> Json:
    wanted = call.access.shown(await _name(call, "service"))
    return {"type": next((t for n, t in await _services(call) if n == wanted), "")}


async def action_servers(call: ServiceCall) -> Json:
    listed = await _visible(call.access, await call.server.directory.actions())
    return {"action_servers": [n for n, _ in listed]}


async def nodes(call: ServiceCall) -> Json:
    robots = {(node, "") for node in await call.server.directory.nodes()}
    return {"nodes": [SERVER_NODE] + [n for n, _ in await _visible(call.access, robots)]}


async def _name(call: ServiceCall, key: str) -> str:
    value = call.arg(key, "")
    if not isinstance(value, str) or not value:
        raise ServiceFailed(f"'{key}' must be a name")
    return await call.access.resolve(value)


async def _param(call: ServiceCall, need: str) -> str:
    name = await _name(call, "name")
    await call.access.require(need, name)
    return name


async def get_param(call: ServiceCall) -> Json:
    """Answer ``value`` as a JSON string, with ROS 2's ``successful`` and ``reason``."""
    name = await _param(call, "see")
    value = await call.server.params.get(name)
    if value is not None:
        return {"value": value, "successful": True, "reason": ""}
    default = call.arg("default_value", call.arg("default", ""))
    found = isinstance(default, str) and default != ""
    reason = "" if found else f"Parameter {names.outside_realm(name)} is not set"
    return {"value": default if found else "null", "successful": found, "reason": reason}


async def set_param(call: ServiceCall) -> Json:
    """Set a parameter; it lives with the caller's connection unless an admin set it (see
    ``telemetry.rosbridge.params``). Raises LimitReached past the connection's parameter budget."""
    name = await _param(call, "set_param")
    value = call.arg("value", "null")
    if not isinstance(value, str):
        raise ServiceFailed("'value' must be a JSON string")
    try:
        json.loads(value)
    except ValueError:
        raise ServiceFailed("'value' is not JSON") from None
    await call.server.params.set(call.conn, name, value)
    return {"successful": True, "reason": ""}


async def delete_param(call: ServiceCall) -> Json:
    name = await _param(call, "set_param")
    found = await call.server.params.delete(call.conn, name)
    reason = "" if found else f"Parameter {names.outside_realm(name)} is not set"
    return {"successful": found, "reason": reason}


async def has_param(call: ServiceCall) -> Json:
    name = await _param(call, "see")
    return {"exists": await call.server.params.get(name) is not None}


async def get_param_names(call: ServiceCall) -> Json:
    listed = await _visible(call.access, ((n, "") for n in await call.server.params.names()))
    return {"names": [n for n, _ in listed]}


async def get_time(_call: ServiceCall) -> Json:
    return {"time": now_stamp()}


def services() -> dict[str, ServerService]:
    handlers = {
        "topics": (topics, "rosapi/Topics"),
        "topic_type": (topic_type, "rosapi/TopicType"),
        "topics_for_type": (topics_for_type, "rosapi/TopicsForType"),
        "services": (list_services, "rosapi/Services"),
        "service_type": (service_type, "rosapi/ServiceType"),
        "action_servers": (action_servers, "rosapi/GetActionServers"),
        "nodes": (nodes, "rosapi/Nodes"),
        "get_param": (get_param, "rosapi/GetParam"),
        "set_param": (set_param, "rosapi/SetParam"),
        "delete_param": (delete_param, "rosapi/DeleteParam"),
        "has_param": (has_param, "rosapi/HasParam"),
        "get_param_names": (get_param_names, "rosapi/GetParamNames"),
        "get_time": (get_time, "rosapi/GetTime"),
    }
    return {
        f"{ROSAPI}/{name}": ServerService(type_name, handler)
        for name, (handler, type_name) in handlers.items()
    }
