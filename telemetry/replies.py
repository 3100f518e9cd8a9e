"""The one place that turns rosbridge errors into what the client receives.

A failed ``call_service`` is answered with ``service_response`` and ``result: false``, the
reason in ``values``; a failed ``send_action_goal`` with a failed ``action_result``. Any
other bad frame is logged and dropped, and the client hears of it only as a ``status``
frame if it asked for that level with ``set_level``. The connection stays up either way.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping
from typing import Any

from telemetry.connection import Connection
from telemetry.domain import protocol
from telemetry.exceptions import RosbridgeError

logger = logging.getLogger("telemetry.rosbridge")


def answer(conn: Connection, error: RosbridgeError, frame: Mapping[str, Any] | None) -> None:
    """Tell ``conn`` (as rosbridge would) that ``frame`` failed with ``error``."""
    frame = frame or {}
    op = error.op or frame.get("op")
    ident = error.id if error.id is not None else frame.get("id")
    logger.info("%s: dropped %s frame: %s", conn.principal.label, op or "a", error.message)
    service, action = frame.get("service"), frame.get("action")
    if op == "call_service" and isinstance(service, str):
        conn.send(dict(protocol.service_response(service, ident, error.message, False)))
    elif op == "send_action_goal" and isinstance(action, str):
        result = protocol.action_result(
            action, ident, error.message, protocol.STATUS_UNKNOWN, False
        )
        conn.send(dict(result))
    else:
        conn.report(error.level, f"{op}: {error.message}" if op else error.message, ident)
