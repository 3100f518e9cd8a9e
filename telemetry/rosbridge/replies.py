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

from telemetry.domain import names, protocol
from telemetry.domain.names import MAX_NAME_LENGTH
from telemetry.exceptions import RosbridgeError
from telemetry.rosbridge.connection import Connection

logger = logging.getLogger("telemetry.rosbridge")
MAX_REASON_LENGTH = 500


def answer(conn: Connection, error: RosbridgeError, frame: Mapping[str, Any] | None) -> None:
    """Tell ``conn`` (as rosbridge would) that ``frame`` failed with ``error``."""
    frame = frame or {}
    op = error.op or _name(frame.get("op"))
    ident = error.id if error.id is not None else protocol.echoable_id(frame.get("id"))
    reason = shortened(names.without_realms(error.message))
    logger.info("%s: dropped %s frame: %s", conn.principal.label, op or "a", reason)
    service, action = _name(frame.get("service")), _name(frame.get("action"))
    if op == "call_service" and service is not None:
        conn.send(dict(protocol.service_response(service, ident, reason, False)))
    elif op == "send_action_goal" and action is not None:
        result = protocol.action_result(action, ident, reason, protocol.STATUS_UNKNOWN, False)
        conn.send(dict(result))
    else:
        conn.report(error.level, f"{op}: {reason}" if op else reason, ident)


def shortened(text: str) -> str:
    """Return ``text`` cut to ``MAX_REASON_LENGTH`` characters, marked where it was cut."""
    if len(text) <= MAX_REASON_LENGTH:
        return text
    return text[: MAX_REASON_LENGTH - 1] + "\u2026"


def _name(value: Any) -> str | None:
    return value if isinstance(value, str) and len(value) <= MAX_NAME_LENGTH else None
