"""ROS 1 message definitions and serialisation of rosbridge JSON, for MCAP recordings.

Recordings carry ROS 1 schemas (``ros1msg``: the type's full definition with its
dependencies after ``===`` lines, the text ``mcap-ros1-support`` and rosbag write) and ROS 1
serialised messages (``ros1``), so Foxglove, Lichtblick, ``rosbag`` and ``rosbags`` open
them. Definitions come from ``rosbags``' ROS 1 Noetic type store; the JSON a client
published is serialised by code compiled once per type (``ros1_layouts``), forgivingly: a
missing field takes its zero value, ``null`` in a float field is NaN (rosbridge writes NaN
and infinity as ``null``), ``uint8[]`` is base64 text or a list of numbers, times are
``sec/nanosec`` or ``secs/nsecs``. A value of the wrong kind raises ``Ros1EncodeError``.
"""

from __future__ import annotations

import base64
import math
import struct
from collections.abc import Mapping
from functools import cache
from typing import Any

import numpy as np
from rosbags.typesys import Stores, get_typestore

from .ros1_layouts import Encoder, compile_encoder

SCHEMA_ENCODING = "ros1msg"
MESSAGE_ENCODING = "ros1"
PROFILE = "ros1"


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
def described(type_name: str) -> tuple[str, bytes] | None:
    """``type_name``'s ROS 1 name and ``ros1msg`` schema (UTF-8), as a recording's schema
    record carries them; None for a type the store does not know."""
    if not known(type_name):
        return None
    return ros1_name(type_name), schema_text(type_name).encode()


@cache
def md5sum(type_name: str) -> str:
    """The ROS 1 MD5 sum of ``type_name`` (what a bag's connection header carries)."""
    _text, md5 = _store().generate_msgdef(store_name(type_name), ros_version=1)
    return str(md5)


def encode(type_name: str, msg: Mapping[str, Any]) -> bytes:
    """Serialise rosbridge JSON ``msg`` as ROS 1 ``type_name``. Raises Ros1EncodeError."""
    try:
        return _encoder(type_name)(msg)
    except (TypeError, ValueError, KeyError, OverflowError, struct.error) as exc:
        raise Ros1EncodeError(f"not a {type_name}: {exc}") from exc


@cache
def _encoder(type_name: str) -> Encoder:
    """The compiled serialiser of ``type_name``, made on first use. Raises KeyError."""
    return compile_encoder(_store().fielddefs, store_name(type_name))


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
