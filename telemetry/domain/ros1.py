"""ROS 1 message definitions and serialisation of rosbridge JSON, for MCAP recordings.

Recordings carry ROS 1 schemas (``ros1msg``: the type's full definition with its
dependencies after ``===`` lines, the text ``mcap-ros1-support`` and rosbag write) and ROS 1
serialised messages (``ros1``), so Foxglove, Lichtblick, ``rosbag`` and ``rosbags`` open
them. Definitions come from ``rosbags``' ROS 1 Noetic type store; the JSON a client
published is turned into that store's message objects field by field, forgivingly: a
missing field takes its zero value, ``null`` in a float field is NaN (rosbridge writes NaN
and infinity as ``null``), ``uint8[]`` is base64 text or a list of numbers, times are
``sec/nanosec`` or ``secs/nsecs``. A value of the wrong kind raises ``Ros1EncodeError``.
"""

from __future__ import annotations

import base64
import binascii
import math
from collections.abc import Callable, Mapping
from functools import cache
from typing import Any

import numpy as np
from rosbags.interfaces import Nodetype
from rosbags.typesys import Stores, get_typestore

SCHEMA_ENCODING = "ros1msg"
MESSAGE_ENCODING = "ros1"
PROFILE = "ros1"

_NUMPY = {
    "bool": np.bool_,
    "int8": np.int8,
    "uint8": np.uint8,
    "byte": np.uint8,
    "char": np.uint8,
    "int16": np.int16,
    "uint16": np.uint16,
    "int32": np.int32,
    "uint32": np.uint32,
    "int64": np.int64,
    "uint64": np.uint64,
    "float32": np.float32,
    "float64": np.float64,
}
_FLOATS = frozenset({"float32", "float64"})


class Ros1EncodeError(ValueError):
    """A message that cannot be written as its ROS 1 type."""


@cache
def _store() -> Any:
    return get_typestore(Stores.ROS1_NOETIC)


def store_name(type_name: str) -> str:
    """``geometry_msgs/PoseStamped`` (or ``geometry_msgs/msg/PoseStamped``) as rosbags names it."""
    package, _, name = type_name.partition("/")
    return f"{package}/msg/{name.rsplit('/', 1)[-1]}"


def ros1_name(type_name: str) -> str:
    """``geometry_msgs/msg/PoseStamped`` as ROS 1 names it: ``geometry_msgs/PoseStamped``."""
    package, _, name = type_name.partition("/")
    return f"{package}/{name.rsplit('/', 1)[-1]}"


def known(type_name: str) -> bool:
    return store_name(type_name) in _store().fielddefs


@cache
def schema_text(type_name: str) -> str:
    """The ROS 1 full definition of ``type_name``. Raises KeyError for an unknown type."""
    text, _md5 = _store().generate_msgdef(store_name(type_name), ros_version=1)
    return str(text)


@cache
def md5sum(type_name: str) -> str:
    """The ROS 1 MD5 sum of ``type_name`` (what a bag's connection header carries)."""
    _text, md5 = _store().generate_msgdef(store_name(type_name), ros_version=1)
    return str(md5)


def encode(type_name: str, msg: Mapping[str, Any]) -> bytes:
    """Serialise rosbridge JSON ``msg`` as ROS 1 ``type_name``. Raises Ros1EncodeError."""
    name = store_name(type_name)
    try:
        obj = _build(name)(msg)
        return bytes(_store().serialize_ros1(obj, name))
    except (TypeError, ValueError, KeyError, OverflowError, binascii.Error) as exc:
        raise Ros1EncodeError(f"not a {type_name}: {exc}") from exc


def decode(type_name: str, data: bytes) -> Any:
    """The rosbags object of ROS 1 bytes ``data`` (for tests and tools)."""
    return _store().deserialize_ros1(data, store_name(type_name))


def to_json(obj: Any) -> Any:
    """A rosbags message object as rosbridge JSON (times ``sec/nanosec``, ``uint8[]`` as
    base64 text, NaN and infinity as ``null``), for pages replaying a recording."""
    if isinstance(obj, np.ndarray):
        if obj.dtype == np.uint8:
            return base64.b64encode(obj.tobytes()).decode()
        if obj.dtype.kind == "f":
            return [v if math.isfinite(v) else None for v in obj.tolist()]
        return obj.tolist()
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, list):
        return [to_json(v) for v in obj]
    fields = getattr(obj, "__dataclass_fields__", None)
    if fields is None:
        return obj
    return {name: to_json(getattr(obj, name)) for name in fields if name != "__msgtype__"}


Builder = Callable[[Any], Any]


@cache
def _build(name: str) -> Builder:
    """A function from JSON to the rosbags object of ``name``, made once per type."""
    if name == "builtin_interfaces/msg/Time" or name == "builtin_interfaces/msg/Duration":
        return _time_builder(name)
    store = _store()
    cls = store.types[name]
    fields = [(field, _field_builder(desc)) for field, desc in store.fielddefs[name][1]]

    def build(value: Any) -> Any:
        if value is None:
            value = {}
        if not isinstance(value, Mapping):
            raise TypeError(f"{name} wants an object")
        return cls(**{field: make(value.get(field)) for field, make in fields})

    return build


def _time_builder(name: str) -> Builder:
    cls = _store().types[name]

    def build(value: Any) -> Any:
        if not isinstance(value, Mapping):
            value = {}
        sec = value.get("sec", value.get("secs", 0)) or 0
        nanosec = value.get("nanosec", value.get("nsecs", 0)) or 0
        return cls(sec=int(sec), nanosec=int(nanosec))

    return build


def _field_builder(desc: tuple[Any, Any]) -> Builder:
    kind, detail = desc
    if kind == Nodetype.NAME:
        return _lazy(detail)
    if kind == Nodetype.BASE:
        return _base_builder(detail[0])
    element, _count = detail
    if element[0] == Nodetype.BASE and element[1][0] in _NUMPY:
        return _array_builder(element[1][0])
    make = _field_builder(element)
    return lambda value: [make(item) for item in (value or [])]


def _lazy(name: str) -> Builder:
    return lambda value: _build(name)(value)


def _base_builder(base: str) -> Builder:
    if base == "string":
        return lambda value: "" if value is None else str(value)
    if base in _FLOATS:
        return lambda value: float("nan") if value is None else float(value)
    if base == "bool":
        return lambda value: bool(value)
    return lambda value: int(value or 0)


def _array_builder(base: str) -> Builder:
    dtype = _NUMPY[base]

    def build(value: Any) -> Any:
        if isinstance(value, str):
            return np.frombuffer(base64.b64decode(value, validate=True), dtype=np.uint8)
        if not value:
            return np.zeros(0, dtype=dtype)
        # numpy reads None as NaN in a float array (rosbridge's null)
        return np.asarray(value, dtype=dtype)

    return build
