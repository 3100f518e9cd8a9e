"""The rosbridge v2 wire format: incoming operations parsed and validated, outgoing frames built.

Every incoming frame becomes one of the ``Op`` dataclasses below, or raises BadFrame. Field
rules follow rosbridge_suite's ``basic_type_check``: a field of the wrong type rejects the
frame; absent optional fields take rosbridge's defaults. Outgoing frames are TypedDicts.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any, NotRequired, TypedDict

from telemetry.exceptions import BadFrame

Json = Any
COMPRESSIONS = frozenset({"none", "cbor", "png", "cbor-raw"})
SUPPORTED_COMPRESSIONS = frozenset({"none", "cbor"})
LEVELS = ("info", "warning", "error", "none")
# An ``id`` names a request in its answer, and the server keeps it while the request
# lasts: a string this long at most, or an integer of CBOR's 64 bits.
MAX_ID_LENGTH = 1024
_ID_RANGE = range(-(2**63), 2**64)
# Message, service and action types (``geometry_msgs/msg/PoseStamped``) are short.
MAX_TYPE_LENGTH = 256


# ---------------------------------------------------------------- incoming operations


@dataclass(slots=True)
class Advertise:
    topic: str
    type: str
    id: Json = None
    latch: bool = False


@dataclass(slots=True)
class Unadvertise:
    topic: str
    id: Json = None


@dataclass(slots=True)
class Publish:
    topic: str
    msg: dict[str, Json]
    id: Json = None
    latch: bool = False


@dataclass(slots=True)
class Subscribe:
    topic: str
    id: Json = None
    type: str | None = None
    throttle_rate: int = 0
    queue_length: int = 0
    fragment_size: int | None = None
    compression: str = "none"


@dataclass(slots=True)
class Unsubscribe:
    topic: str
    id: Json = None


@dataclass(slots=True)
class CallService:
    service: str
    id: Json = None
    args: Json = field(default_factory=dict)
    type: str | None = None
    fragment_size: int | None = None
    compression: str = "none"


@dataclass(slots=True)
class ServiceResponse:
    service: str
    result: bool
    id: Json = None
    values: Json = None


@dataclass(slots=True)
class AdvertiseService:
    service: str
    type: str


@dataclass(slots=True)
class UnadvertiseService:
    service: str


@dataclass(slots=True)
class AdvertiseAction:
    action: str
    type: str


@dataclass(slots=True)
class UnadvertiseAction:
    action: str


@dataclass(slots=True)
class SendActionGoal:
    action: str
    action_type: str
    id: Json = None
    args: Json = field(default_factory=dict)
    feedback: bool = False
    fragment_size: int | None = None
    compression: str = "none"


@dataclass(slots=True)
class CancelActionGoal:
    action: str
    id: Json = None


@dataclass(slots=True)
class ActionFeedback:
    action: str
    id: Json = None
    values: Json = None


@dataclass(slots=True)
class ActionResult:
    action: str
    status: int
    result: bool
    id: Json = None
    values: Json = None


@dataclass(slots=True)
class Fragment:
    id: Json
    data: str
    num: int
    total: int


@dataclass(slots=True)
class SetLevel:
    level: str
    id: Json = None


Op = (
    Advertise
    | Unadvertise
    | Publish
    | Subscribe
    | Unsubscribe
    | CallService
    | ServiceResponse
    | AdvertiseService
    | UnadvertiseService
    | AdvertiseAction
    | UnadvertiseAction
    | SendActionGoal
    | CancelActionGoal
    | ActionFeedback
    | ActionResult
    | Fragment
    | SetLevel
)


# ---------------------------------------------------------------- validation


def parse_op(frame: Mapping[str, Json]) -> Op:
    """Return the operation ``frame`` asks for. Raises BadFrame naming the first fault."""
    op = frame.get("op")
    if not isinstance(op, str):
        raise BadFrame("frame has no 'op'", id=_id(frame))
    parser = _PARSERS.get(op)
    if parser is None:
        raise BadFrame(f"unknown operation: {op}", op=op, id=_id(frame))
    try:
        return parser(_Fields(frame, op))
    except _FieldError as exc:
        raise BadFrame(f"{op}: {exc}", op=op, id=_id(frame)) from None


class _FieldError(Exception):
    pass


def echoable_id(value: Json) -> str | int | None:
    """Return ``value`` if it may name a frame in an answer, else None.

    Only a string of at most ``MAX_ID_LENGTH`` characters or a 64-bit integer is ever
    echoed: anything else a client put there stays with the frame that is dropped.
    """
    if isinstance(value, str):
        return value if len(value) <= MAX_ID_LENGTH else None
    if isinstance(value, int) and not isinstance(value, bool) and value in _ID_RANGE:
        return value
    return None


def _id(frame: Mapping[str, Json]) -> str | int | None:
    return echoable_id(frame.get("id"))


class _Fields:
    """Typed access to a frame's fields; each accessor raises _FieldError on a wrong type."""

    __slots__ = ("frame", "op")

    def __init__(self, frame: Mapping[str, Json], op: str) -> None:
        self.frame = frame
        self.op = op

    def _get(self, key: str, required: bool) -> Json:
        value = self.frame.get(key)
        if value is None and required:
            raise _FieldError(f"missing '{key}'")
        return value

    def text(self, key: str) -> str:
        value = self._get(key, True)
        if not isinstance(value, str):
            raise _FieldError(f"'{key}' must be a string")
        return value

    def opt_text(self, key: str, default: str | None = None) -> str | None:
        return default if self.frame.get(key) is None else self.text(key)

    def integer(self, key: str) -> int:
        value = self._get(key, True)
        # JSON has one number type; rosbridge accepts 10.0 where it wants 10, we do too.
        if isinstance(value, float) and value.is_integer():
            value = int(value)
        if not isinstance(value, int) or isinstance(value, bool):
            raise _FieldError(f"'{key}' must be an integer")
        return value

    def opt_integer(self, key: str, default: int | None = None, minimum: int = 0) -> int | None:
        if self.frame.get(key) is None:
            return default
        value = self.integer(key)
        if value < minimum:
            raise _FieldError(f"'{key}' must be at least {minimum}")
        return value

    def boolean(self, key: str, default: bool | None = None) -> bool:
        value = self.frame.get(key)
        if value is None and default is not None:
            return default
        if not isinstance(value, bool):
            raise _FieldError(f"'{key}' must be a boolean")
        return value

    def mapping(self, key: str) -> dict[str, Json]:
        value = self.frame.get(key)
        if value is None:
            return {}
        if not isinstance(value, dict):
            raise _FieldError(f"'{key}' must be an object")
        return value

    def args(self, key: str) -> Json:
        value = self.frame.get(key)
        if value is None:
            return {}
        if not isinstance(value, dict | list):
            raise _FieldError(f"'{key}' must be an object or a list")
        return value

    def compression(self) -> str:
        value = self.opt_text("compression", "none") or "none"
        if value not in COMPRESSIONS:
            raise _FieldError(f"unknown compression '{value}'")
        return value

    def level(self) -> str:
        value = self.text("level")
        if value not in LEVELS:
            raise _FieldError(f"level must be one of {', '.join(LEVELS)}")
        return value

    def type_name(self, key: str) -> str:
        value = self.text(key)
        if len(value) > MAX_TYPE_LENGTH:
            raise _FieldError(f"'{key}' is longer than {MAX_TYPE_LENGTH} characters")
        return value

    def opt_type_name(self, key: str) -> str | None:
        return None if self.frame.get(key) is None else self.type_name(key)

    @property
    def id(self) -> str | int | None:
        value = self.frame.get("id")
        if value is not None and echoable_id(value) is None:
            raise _FieldError(
                f"'id' must be a string of at most {MAX_ID_LENGTH} characters or a 64-bit integer"
            )
        return value


def _subscribe(f: _Fields) -> Subscribe:
    return Subscribe(
        topic=f.text("topic"),
        id=f.id,
        type=f.opt_type_name("type"),
        throttle_rate=f.opt_integer("throttle_rate", 0) or 0,
        queue_length=f.opt_integer("queue_length", 0) or 0,
        fragment_size=f.opt_integer("fragment_size", None, minimum=1),
        compression=f.compression(),
    )


def _call_service(f: _Fields) -> CallService:
    return CallService(
        service=f.text("service"),
        id=f.id,
        args=f.args("args"),
        type=f.opt_type_name("type"),
        fragment_size=f.opt_integer("fragment_size", None, minimum=1),
        compression=f.compression(),
    )


def _send_action_goal(f: _Fields) -> SendActionGoal:
    return SendActionGoal(
        action=f.text("action"),
        action_type=f.type_name("action_type"),
        id=f.id,
        args=f.args("args"),
        feedback=f.boolean("feedback", False),
        fragment_size=f.opt_integer("fragment_size", None, minimum=1),
        compression=f.compression(),
    )


def _fragment(f: _Fields) -> Fragment:
    if f.id is None:
        raise _FieldError("missing 'id'")
    return Fragment(id=f.id, data=f.text("data"), num=f.integer("num"), total=f.integer("total"))


_PARSERS: dict[str, Callable[[_Fields], Op]] = {
    "advertise": lambda f: Advertise(
        topic=f.text("topic"), type=f.type_name("type"), id=f.id, latch=f.boolean("latch", False)
    ),
    "unadvertise": lambda f: Unadvertise(topic=f.text("topic"), id=f.id),
    "publish": lambda f: Publish(
        topic=f.text("topic"), msg=f.mapping("msg"), id=f.id, latch=f.boolean("latch", False)
    ),
    "subscribe": _subscribe,
    "unsubscribe": lambda f: Unsubscribe(topic=f.text("topic"), id=f.id),
    "call_service": _call_service,
    "service_response": lambda f: ServiceResponse(
        service=f.text("service"),
        result=f.boolean("result"),
        id=f.id,
        values=f.frame.get("values"),
    ),
    "advertise_service": lambda f: AdvertiseService(
        service=f.text("service"), type=f.type_name("type")
    ),
    "unadvertise_service": lambda f: UnadvertiseService(service=f.text("service")),
    "advertise_action": lambda f: AdvertiseAction(
        action=f.text("action"), type=f.type_name("type")
    ),
    "unadvertise_action": lambda f: UnadvertiseAction(action=f.text("action")),
    "send_action_goal": _send_action_goal,
    "cancel_action_goal": lambda f: CancelActionGoal(action=f.text("action"), id=f.id),
    "action_feedback": lambda f: ActionFeedback(
        action=f.text("action"), id=f.id, values=f.frame.get("values")
    ),
    "action_result": lambda f: ActionResult(
        action=f.text("action"),
        status=f.integer("status"),
        result=f.boolean("result"),
        id=f.id,
        values=f.frame.get("values"),
    ),
    "fragment": _fragment,
    "set_level": lambda f: SetLevel(level=f.level(), id=f.id),
}


# ---------------------------------------------------------------- outgoing frames


class PublishFrame(TypedDict):
    op: str
    topic: str
    msg: dict[str, Json]


class CallServiceFrame(TypedDict):
    op: str
    id: Json
    service: str
    args: Json


class ServiceResponseFrame(TypedDict):
    op: str
    service: str
    values: Json
    result: bool
    id: NotRequired[Json]


class SendActionGoalFrame(TypedDict):
    op: str
    id: Json
    action: str
    action_type: str
    args: Json
    feedback: bool


class CancelActionGoalFrame(TypedDict):
    op: str
    id: Json
    action: str


class ActionFeedbackFrame(TypedDict):
    op: str
    action: str
    values: Json
    id: NotRequired[Json]


class ActionResultFrame(TypedDict):
    op: str
    action: str
    values: Json
    status: int
    result: bool
    id: NotRequired[Json]


class StatusFrame(TypedDict):
    op: str
    level: str
    msg: str
    id: NotRequired[Json]


class FragmentFrame(TypedDict):
    op: str
    id: Json
    data: str
    num: int
    total: int


OutFrame = (
    PublishFrame
    | CallServiceFrame
    | ServiceResponseFrame
    | SendActionGoalFrame
    | CancelActionGoalFrame
    | ActionFeedbackFrame
    | ActionResultFrame
    | StatusFrame
    | FragmentFrame
)

# action_msgs/GoalStatus
STATUS_UNKNOWN = 0


def service_response(service: str, id: Json, values: Json, result: bool) -> ServiceResponseFrame:
    """Build a service answer; the ``id`` is left out when the call had none, as rosbridge does."""
    frame = ServiceResponseFrame(
        op="service_response", service=service, values=values, result=result
    )
    if id is not None:
        frame["id"] = id
    return frame


def call_service(service: str, id: Json, args: Json) -> CallServiceFrame:
    return CallServiceFrame(op="call_service", id=id, service=service, args=args)


def send_action_goal(action: str, id: Json, action_type: str, args: Json) -> SendActionGoalFrame:
    return SendActionGoalFrame(
        op="send_action_goal",
        id=id,
        action=action,
        action_type=action_type,
        args=args,
        feedback=True,
    )


def cancel_action_goal(action: str, id: Json) -> CancelActionGoalFrame:
    return CancelActionGoalFrame(op="cancel_action_goal", id=id, action=action)


def action_feedback(action: str, id: Json, values: Json) -> ActionFeedbackFrame:
    frame = ActionFeedbackFrame(op="action_feedback", action=action, values=values)
    if id is not None:
        frame["id"] = id
    return frame


def action_result(
    action: str, id: Json, values: Json, status: int, result: bool
) -> ActionResultFrame:
    frame = ActionResultFrame(
        op="action_result", action=action, values=values, status=status, result=result
    )
    if id is not None:
        frame["id"] = id
    return frame


def status(level: str, msg: str, id: Json = None) -> StatusFrame:
    frame = StatusFrame(op="status", level=level, msg=msg)
    if id is not None:
        frame["id"] = id
    return frame


def level_shows(chosen: str, level: str) -> bool:
    """True if a client that asked for ``chosen`` wants a status of ``level``.

    ``info`` shows everything, ``error`` only errors, ``none`` nothing (the default).
    """
    if chosen == "none" or level not in LEVELS:
        return False
    return LEVELS.index(level) >= LEVELS.index(chosen)
