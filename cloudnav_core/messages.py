"""ROS messages as rosbridge JSON: their schemas, the builders that write them, and the
readers of the ones received. The server and the robot agent both use this module.

Conventions (rosbridge's JSON): a time is ``{"sec", "nanosec"}`` (``cloudnav_core.times``
adds ROS 1's ``secs/nsecs`` where the server writes for clients of both generations);
``uint8[]`` fields are base64 text; NaN and infinity cannot be written in JSON and become
``null``, so a ``LaserScan`` range with no return (REP 117's ``+inf``) is ``null``.

Builders return the ``TypedDict`` of their message and take a stamp either as seconds
(since the epoch, or of a simulated clock) or as a ready ``Time``. Readers take whatever
arrived (an untrusted mapping) and return None for a message they cannot use: a bad
message from the network must never stop a robot's loop or the server's relay.
"""

from __future__ import annotations

import base64
import json
import math
import struct
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from enum import IntEnum
from itertools import pairwise
from typing import Any, NotRequired, TypedDict

import cv2
import numpy as np
from numpy.typing import NDArray

from cloudnav_core import se2

NANOS = 1_000_000_000

Json = dict[str, Any]
"""A JSON object as a rosbridge client sends and receives it."""
Message = Mapping[str, Any]
"""Any ROS message in rosbridge JSON: what readers take and senders send."""


# --- schemas ---------------------------------------------------------------------------


class Time(TypedDict):
    """``builtin_interfaces/Time`` (ROS 1's ``time`` spelled ``secs/nsecs`` too)."""

    sec: int
    nanosec: int
    secs: NotRequired[int]
    nsecs: NotRequired[int]


class Header(TypedDict):
    """``std_msgs/Header``."""

    stamp: Time
    frame_id: str


class Vector3(TypedDict):
    """``geometry_msgs/Vector3``; ``geometry_msgs/Point`` has the same fields."""

    x: float
    y: float
    z: float


Point = Vector3


class Quaternion(TypedDict):
    """``geometry_msgs/Quaternion``."""

    x: float
    y: float
    z: float
    w: float


class Pose(TypedDict):
    """``geometry_msgs/Pose``."""

    position: Point
    orientation: Quaternion


class PoseStamped(TypedDict):
    """``geometry_msgs/PoseStamped``: a robot's ``pose`` and an operator's ``goal``."""

    header: Header
    pose: Pose


class PoseWithCovariance(TypedDict):
    """``geometry_msgs/PoseWithCovariance``: ``covariance`` is row-major 6x6 over (x, y,
    z, roll, pitch, yaw)."""

    pose: Pose
    covariance: list[float]


class PoseWithCovarianceStamped(TypedDict):
    """``geometry_msgs/PoseWithCovarianceStamped``: an operator's ``initialpose``."""

    header: Header
    pose: PoseWithCovariance


class Twist(TypedDict):
    """``geometry_msgs/Twist``: ``cmd_vel``."""

    linear: Vector3
    angular: Vector3


class TwistWithCovariance(TypedDict):
    """``geometry_msgs/TwistWithCovariance`` (covariance as ``PoseWithCovariance``'s)."""

    twist: Twist
    covariance: list[float]


class Odometry(TypedDict):
    """``nav_msgs/Odometry``: ``odom``."""

    header: Header
    child_frame_id: str
    pose: PoseWithCovariance
    twist: TwistWithCovariance


class ScanGeometry(TypedDict):
    """A ``sensor_msgs/LaserScan`` but its header and readings: its beams and range."""

    angle_min: float
    angle_max: float
    angle_increment: float
    time_increment: float
    scan_time: float
    range_min: float
    range_max: float


class LaserScan(ScanGeometry):
    """``sensor_msgs/LaserScan``: ``scan``; a range without a return is ``None``."""

    header: Header
    ranges: list[float | None]
    intensities: list[float]


class Path(TypedDict):
    """``nav_msgs/Path``: ``plan``, and the cloud's ``plan_path`` answer."""

    header: Header
    poses: list[PoseStamped]


class GoalID(TypedDict):
    """``actionlib_msgs/GoalID``."""

    stamp: Time
    id: str


class GoalStatusMsg(TypedDict):
    """``actionlib_msgs/GoalStatus`` (its ``status`` values are ``GoalStatus``)."""

    goal_id: GoalID
    status: int
    text: str


class GoalStatusArray(TypedDict):
    """``actionlib_msgs/GoalStatusArray``: ``nav_status``."""

    header: Header
    status_list: list[GoalStatusMsg]


class String(TypedDict):
    """``std_msgs/String``: ``map_id``."""

    data: str


class CompressedImage(TypedDict):
    """``sensor_msgs/CompressedImage``: ``camera/image/compressed``; ``data`` in base64."""

    header: Header
    format: str
    data: str


class Image(TypedDict):
    """``sensor_msgs/Image``: ``camera/depth/image`` (``16UC1``, millimetres, 0 where the
    sensor has no reading, as OpenNI cameras publish it); ``data`` in base64."""

    header: Header
    height: int
    width: int
    encoding: str
    is_bigendian: int
    step: int
    data: str


class PinholeCalibration(TypedDict):
    """A ``sensor_msgs/CameraInfo`` but its header: a pinhole camera's calibration, in
    ROS 1's (and rosbridge's) names; ROS 2 spells the matrices ``d``, ``k``, ``r``, ``p``."""

    height: int
    width: int
    distortion_model: str
    D: list[float]
    K: list[float]
    R: list[float]
    P: list[float]


class CameraInfo(PinholeCalibration):
    """``sensor_msgs/CameraInfo``: ``camera/camera_info``."""

    header: Header


class KeyValue(TypedDict):
    """``diagnostic_msgs/KeyValue``."""

    key: str
    value: str


class DiagnosticStatus(TypedDict):
    """``diagnostic_msgs/DiagnosticStatus``: ``localisation``. ``level`` 0 OK, 1 WARN,
    2 ERROR, 3 STALE."""

    level: int
    name: str
    message: str
    hardware_id: str
    values: list[KeyValue]


class BatteryState(TypedDict):
    """``sensor_msgs/BatteryState``, the fields the fleet uses (rosbridge fills no others)."""

    header: Header
    voltage: float
    percentage: float
    power_supply_status: int
    present: bool


POWER_SUPPLY_STATUS_DISCHARGING = 2


class GoalStatus(IntEnum):
    """``actionlib_msgs/GoalStatus`` values."""

    PENDING = 0
    ACTIVE = 1
    PREEMPTED = 2
    SUCCEEDED = 3
    ABORTED = 4
    REJECTED = 5
    PREEMPTING = 6
    RECALLING = 7
    RECALLED = 8
    LOST = 9

    @property
    def terminal(self) -> bool:
        """Whether a goal in this state is finished for good."""
        return self in _TERMINAL


_TERMINAL = frozenset(
    {
        GoalStatus.PREEMPTED,
        GoalStatus.SUCCEEDED,
        GoalStatus.ABORTED,
        GoalStatus.REJECTED,
        GoalStatus.RECALLED,
        GoalStatus.LOST,
    }
)


@dataclass(frozen=True)
class StatusEntry:
    """One goal's line in a ``GoalStatusArray``."""

    goal_id: str
    stamp: float
    status: GoalStatus
    text: str = ""


@dataclass(frozen=True, slots=True)
class Pose2D:
    """Where a robot is: its sub-map (Map ID) and its planar pose in that map's frame."""

    map_id: str
    x: float
    y: float
    yaw: float


Stamp = float | Time
"""Seconds (since the epoch, or of a simulated clock), or a ready ``Time``."""
PlanarCovariance = Sequence[Sequence[float]] | NDArray[np.float64]
"""A 3x3 covariance over (x, y, yaw)."""


# --- builders --------------------------------------------------------------------------


def ros_time(seconds: float) -> Time:
    """``builtin_interfaces/Time`` of ``seconds``, to the nearest nanosecond (the whole
    and fractional parts are taken apart first: an epoch time in nanoseconds is more
    than a float holds exactly)."""
    fraction, whole = math.modf(seconds)
    sec, nanosec = divmod(round(fraction * NANOS), NANOS)
    return {"sec": int(whole) + sec, "nanosec": nanosec}


def header(frame_id: str, stamp: Stamp) -> Header:
    """``std_msgs/Header``."""
    return {"stamp": _time(stamp), "frame_id": frame_id}


def _time(stamp: Stamp) -> Time:
    return stamp if isinstance(stamp, dict) else ros_time(stamp)


def quaternion_from_yaw(yaw: float) -> Quaternion:
    """``geometry_msgs/Quaternion`` of a rotation by ``yaw`` about z."""
    return {"x": 0.0, "y": 0.0, "z": math.sin(yaw / 2), "w": math.cos(yaw / 2)}


def pose_2d(x: float, y: float, yaw: float) -> Pose:
    """``geometry_msgs/Pose`` on the floor plane."""
    return {"position": {"x": x, "y": y, "z": 0.0}, "orientation": quaternion_from_yaw(yaw)}


def pose_stamped(frame_id: str, pose: se2.Pose, stamp: Stamp) -> PoseStamped:
    """``geometry_msgs/PoseStamped`` of a planar ``pose`` in ``frame_id`` (a Map ID)."""
    return {"header": header(frame_id, stamp), "pose": pose_2d(*pose)}


def covariance_6x6(planar: PlanarCovariance) -> list[float]:
    """Row-major 6x6 covariance over (x, y, z, roll, pitch, yaw) of a 3x3 one over (x, y,
    yaw); z, roll and pitch are fixed (zero)."""
    values = [0.0] * 36
    for row, line in zip(_PLANAR, planar, strict=True):
        for col, value in zip(_PLANAR, line, strict=True):
            values[6 * row + col] = float(value)
    return values


_PLANAR = [0, 1, 5]
"""Rows and columns of x, y and yaw in a 6x6 covariance."""


def twist_2d(linear: float, angular: float) -> Twist:
    """``geometry_msgs/Twist`` of a planar robot (``twist_2d(0.0, 0.0)`` stops it)."""
    return {
        "linear": {"x": linear, "y": 0.0, "z": 0.0},
        "angular": {"x": 0.0, "y": 0.0, "z": angular},
    }


def odometry(
    frame_id: str,
    child_frame_id: str,
    stamp: Stamp,
    *,
    pose: se2.Pose,
    pose_covariance: PlanarCovariance,
    velocity: tuple[float, float],
    velocity_covariance: PlanarCovariance,
) -> Odometry:
    """``nav_msgs/Odometry``: ``pose`` in ``frame_id`` (``odom``), ``velocity`` ``(linear,
    angular)`` in ``child_frame_id`` (the robot's base), each with its covariance."""
    return {
        "header": header(frame_id, stamp),
        "child_frame_id": child_frame_id,
        "pose": {"pose": pose_2d(*pose), "covariance": covariance_6x6(pose_covariance)},
        "twist": {
            "twist": twist_2d(*velocity),
            "covariance": covariance_6x6(velocity_covariance),
        },
    }


def laser_scan(
    frame_id: str,
    ranges: Iterable[float],
    stamp: Stamp,
    *,
    angle_min: float,
    angle_max: float,
    angle_increment: float,
    time_increment: float,
    scan_time: float,
    range_min: float,
    range_max: float,
) -> LaserScan:
    """``sensor_msgs/LaserScan`` of ``ranges`` (metres); a range without a return
    (``inf``, NaN) becomes ``None``."""
    return {
        "header": header(frame_id, stamp),
        "angle_min": angle_min,
        "angle_max": angle_max,
        "angle_increment": angle_increment,
        "time_increment": time_increment,
        "scan_time": scan_time,
        "range_min": range_min,
        "range_max": range_max,
        "ranges": [float(r) if math.isfinite(r) else None for r in ranges],
        "intensities": [],
    }


def scan_ranges(values: Sequence[float | None] | NDArray[Any]) -> NDArray[np.float64]:
    """A ``LaserScan``'s ranges as floats, with rosbridge's ``null`` (no return) as NaN."""
    if isinstance(values, np.ndarray):
        return values.astype(np.float64)
    return np.array([math.nan if v is None else v for v in values], np.float64)


def path_of(frame_id: str, poses: Iterable[se2.Pose], stamp: Stamp) -> Path:
    """``nav_msgs/Path`` of ``poses``, each stamped as the path."""
    return {
        "header": header(frame_id, stamp),
        "poses": [pose_stamped(frame_id, pose, stamp) for pose in poses],
    }


def path_message(frame_id: str, points: Sequence[se2.Point], stamp: Stamp) -> Path:
    """``nav_msgs/Path`` through ``points``, each pose facing the next point (the last
    keeps its predecessor's heading); an empty path clears the plan."""
    headings = [math.atan2(b[1] - a[1], b[0] - a[0]) for a, b in pairwise(points)]
    if points:
        headings.append(headings[-1] if headings else 0.0)
    return path_of(frame_id, ((*p, yaw) for p, yaw in zip(points, headings, strict=True)), stamp)


def status_array(entries: Iterable[StatusEntry], stamp: Stamp) -> GoalStatusArray:
    """``actionlib_msgs/GoalStatusArray`` of ``entries``."""
    return {
        "header": header("", stamp),
        "status_list": [
            {
                "goal_id": {"stamp": ros_time(e.stamp), "id": e.goal_id},
                "status": int(e.status),
                "text": e.text,
            }
            for e in entries
        ],
    }


def string_message(data: str) -> String:
    """``std_msgs/String``."""
    return {"data": data}


def battery_state(percentage: float, voltage: float, stamp: Stamp) -> BatteryState:
    """``sensor_msgs/BatteryState`` of a discharging battery; ``percentage`` is 0..1."""
    return {
        "header": header("", stamp),
        "voltage": voltage,
        "percentage": percentage,
        "power_supply_status": POWER_SUPPLY_STATUS_DISCHARGING,
        "present": True,
    }


def diagnostic_status(
    level: int, name: str, message: str, values: Mapping[str, str]
) -> DiagnosticStatus:
    """``diagnostic_msgs/DiagnosticStatus`` of ``values`` (in their order)."""
    return {
        "level": level,
        "name": name,
        "message": message,
        "hardware_id": "",
        "values": [{"key": key, "value": value} for key, value in values.items()],
    }


def compressed_image(frame_id: str, jpeg: bytes, stamp: Stamp) -> CompressedImage:
    """``sensor_msgs/CompressedImage`` of ``jpeg`` (format ``jpeg``)."""
    return {
        "header": header(frame_id, stamp),
        "format": "jpeg",
        "data": base64.b64encode(jpeg).decode("ascii"),
    }


DEPTH_ENCODING = "16UC1"
MAX_DEPTH_MM = 65535
COMPRESSED_DEPTH_FORMAT = "16UC1; compressedDepth png"
"""``CompressedImage.format`` of depth as ROS's ``compressed_depth_image_transport``
publishes it (the ``camera/depth/image/compressedDepth`` topic): a 12-byte header, then
a 16-bit grey PNG of millimetres."""
COMPRESSED_DEPTH_HEADER = struct.Struct("<iff")
"""The header before the PNG: ``compressionFormat`` (0: inverse depth) and the two
``depthParam`` quantisation factors (used by 32FC1 depth only; zero for 16UC1)."""
PNG_LEVEL = 6
"""zlib level of the depth PNG. A rendered 640x480 depth image: level 1 5.6 kB in 4 ms,
6 3.5 kB in 7 ms, 9 3.1 kB in 12 ms; the raw ``Image`` is 819 kB of JSON."""


def _millimetres(depth_m: NDArray[np.floating[Any]]) -> NDArray[np.uint16]:
    """Depth in metres as millimetres, 0 where there is no reading (not finite, not
    positive, or past 65.535 m)."""
    millimetres = np.rint(np.nan_to_num(depth_m, nan=0.0, posinf=0.0, neginf=0.0) * 1000.0)
    millimetres[(millimetres <= 0) | (millimetres > MAX_DEPTH_MM)] = 0
    return np.ascontiguousarray(millimetres, dtype="<u2")


def depth_image(frame_id: str, depth_m: NDArray[np.floating[Any]], stamp: Stamp) -> Image:
    """``sensor_msgs/Image`` of a depth image in metres: ``16UC1`` millimetres, 0 where
    there is no reading."""
    data = _millimetres(depth_m)
    height, width = data.shape
    return {
        "header": header(frame_id, stamp),
        "height": height,
        "width": width,
        "encoding": DEPTH_ENCODING,
        "is_bigendian": 0,
        "step": 2 * width,
        "data": base64.b64encode(data.tobytes()).decode("ascii"),
    }


def compressed_depth(
    frame_id: str, depth_m: NDArray[np.floating[Any]], stamp: Stamp
) -> CompressedImage:
    """``sensor_msgs/CompressedImage`` of a depth image in metres, as ROS's
    ``compressedDepth`` transport writes 16UC1 depth (``COMPRESSED_DEPTH_FORMAT``):
    lossless, millimetres, 0 where there is no reading."""
    ok, png = cv2.imencode(".png", _millimetres(depth_m), [cv2.IMWRITE_PNG_COMPRESSION, PNG_LEVEL])
    if not ok:
        raise ValueError("the depth image could not be written as PNG")
    data = COMPRESSED_DEPTH_HEADER.pack(0, 0.0, 0.0) + png.tobytes()
    return {
        "header": header(frame_id, stamp),
        "format": COMPRESSED_DEPTH_FORMAT,
        "data": base64.b64encode(data).decode("ascii"),
    }


def camera_info(frame_id: str, calibration: PinholeCalibration, stamp: Stamp) -> CameraInfo:
    """``sensor_msgs/CameraInfo`` of ``calibration``
    (``robots.agent.perception.pinhole_calibration``)."""
    return {"header": header(frame_id, stamp), **calibration}


# --- readers ---------------------------------------------------------------------------


def depth_of(msg: Message, max_pixels: int) -> NDArray[np.float32] | None:
    """Metres (float32, ``nan`` where there is no reading) of a depth message: a
    ``sensor_msgs/Image`` (``16UC1`` millimetres or ``32FC1`` metres) or a
    ``sensor_msgs/CompressedImage`` of ROS's ``compressedDepth`` transport (a message
    with a ``format``). None for anything else, for more than ``max_pixels`` pixels, or
    for data that does not fill the image."""
    if "format" in msg:
        return _compressed_depth_of(msg, max_pixels)
    try:
        height, width, step = int(msg["height"]), int(msg["width"]), int(msg["step"])
        encoding, data = str(msg["encoding"]), base64.b64decode(msg["data"], validate=True)
        big = bool(msg.get("is_bigendian", 0))
    except (KeyError, TypeError, ValueError):
        return None
    size = {"16UC1": 2, "mono16": 2, "32FC1": 4}.get(encoding)
    if size is None or not (height > 0 and width > 0 and height * width <= max_pixels):
        return None
    if step < width * size:
        return None
    if len(data) != height * step:
        return None
    kind = "u2" if size == 2 else "f4"
    rows = np.frombuffer(data, np.uint8).reshape(height, step)[:, : width * size]
    values = rows.copy().view((">" if big else "<") + kind).reshape(height, width)
    return _metres(values.astype(np.float32) / (1000.0 if size == 2 else 1.0))


def _metres(depth: NDArray[np.float32]) -> NDArray[np.float32]:
    depth[~np.isfinite(depth) | (depth <= 0)] = np.nan
    return depth


PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def _compressed_depth_of(msg: Message, max_pixels: int) -> NDArray[np.float32] | None:
    """Metres of a ``compressedDepth`` message: ``16UC1`` (PNG of millimetres) or
    ``32FC1`` (PNG of quantised inverse depth, ``depthParam`` A / (value - B) metres).
    The PNG's size is read from its header before anything is inflated."""
    try:
        encoding, _, transport = str(msg["format"]).partition(";")
        data = base64.b64decode(msg["data"], validate=True)
    except (KeyError, TypeError, ValueError):
        return None
    encoding, codec = encoding.strip(), transport.split()
    # "compressedDepth" alone is the older transport's spelling of the same PNG form.
    if encoding not in {"16UC1", "32FC1"} or codec not in (
        ["compressedDepth"],
        ["compressedDepth", "png"],
    ):
        return None
    if len(data) < COMPRESSED_DEPTH_HEADER.size + 26:
        return None
    _, quant_a, quant_b = COMPRESSED_DEPTH_HEADER.unpack_from(data)
    png = data[COMPRESSED_DEPTH_HEADER.size :]
    width, height = struct.unpack_from(">II", png, 16)
    header_ok = png.startswith(PNG_SIGNATURE) and png[12:16] == b"IHDR"
    grey16 = png[24] == 16 and png[25] == 0  # bit depth, colour type
    if not (header_ok and grey16 and 0 < width * height <= max_pixels):
        return None
    values = cv2.imdecode(np.frombuffer(png, np.uint8), cv2.IMREAD_UNCHANGED)
    if values is None or values.dtype != np.uint16 or values.shape != (height, width):
        return None
    if encoding == "16UC1":
        return _metres(values.astype(np.float32) / 1000.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        inverse = values.astype(np.float32)
        depth = np.where(values > 0, np.float32(quant_a) / (inverse - np.float32(quant_b)), np.nan)
    return _metres(depth.astype(np.float32))


def yaw_of(q: Mapping[str, Any]) -> float:
    """Return the rotation about z of a quaternion ``{x, y, z, w}``, in radians."""
    get = q.get  # four plain look-ups: this runs for every pose the server hears
    x, y = float(get("x", 0.0) or 0.0), float(get("y", 0.0) or 0.0)
    z, w = float(get("z", 0.0) or 0.0), float(get("w", 0.0) or 0.0)
    return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def pose_of(msg: Message) -> Pose2D | None:
    """Return the planar pose in a ``geometry_msgs/PoseStamped``, or None if it has none."""
    try:
        pose = msg["pose"]
        position = pose["position"]
        frame = msg.get("header", {}).get("frame_id")
        return Pose2D(
            map_id=frame if isinstance(frame, str) else "",  # a null frame is no frame
            x=float(position["x"]),
            y=float(position["y"]),
            yaw=yaw_of(pose.get("orientation", {})),
        )
    except (KeyError, TypeError, ValueError, AttributeError):
        return None


_last_published: tuple[Message, Pose2D | None] = ({}, None)


def published_pose_of(msg: Message) -> Pose2D | None:
    """``pose_of`` for a message on the topic bus, parsed once however many readers ask.

    The fleet state, the event log and map upkeep each read the pose of every robot's
    ``pose`` message; the bus hands them the same object, which no one changes (see
    ``telemetry.domain.bus``), so the newest answer is kept with the message it came
    from and given again for that very object. The message is held, so its identity
    cannot pass to another one meanwhile.
    """
    global _last_published
    last = _last_published  # one read: another event loop's thread may replace it
    if last[0] is msg:
        return last[1]
    pose = pose_of(msg)
    _last_published = (msg, pose)
    return pose


def path_points_of(msg: Message) -> tuple[str, list[se2.Point]] | None:
    """The frame (a Map ID) and points of a ``nav_msgs/Path``, or None if it is not one
    (a point without a finite position included)."""
    try:
        frame = msg["header"]["frame_id"]
        points = [
            (float(p["pose"]["position"]["x"]), float(p["pose"]["position"]["y"]))
            for p in msg["poses"]
        ]
    except (KeyError, TypeError, ValueError, AttributeError):
        return None
    if not isinstance(frame, str) or not all(_finite(*p) for p in points):
        return None
    return frame, points


@dataclass(frozen=True)
class WaitOrder:
    """The cloud's word on a robot's ``right_of_way`` topic that it must wait: at ``spot``
    (x, y, yaw in sub-map ``map_id``) until ``waiting_for`` has passed the narrow place
    at ``place``. No order (``go``) lets it drive on."""

    map_id: str
    spot: se2.Pose
    place: se2.Point
    waiting_for: str
    message: str = ""


def right_of_way_message(order: WaitOrder | None, message: str = "") -> String:
    """``std_msgs/String`` on ``/r/right_of_way``: ``data`` is JSON, ``{"state": "go",
    "message"}`` or ``{"state": "wait", "map_id", "spot": [x, y, yaw], "place": [x, y],
    "waiting_for", "message"}``."""
    if order is None:
        return string_message(json.dumps({"state": "go", "message": message}))
    body = {
        "state": "wait",
        "map_id": order.map_id,
        "spot": [round(v, 3) for v in order.spot],
        "place": [round(v, 3) for v in order.place],
        "waiting_for": order.waiting_for,
        "message": order.message,
    }
    return string_message(json.dumps(body))


def wait_order_of(msg: Message) -> WaitOrder | None:
    """The wait order in a ``right_of_way`` message; None for ``go`` or a message that is
    not one (a robot drives on rather than stop on a word it cannot read)."""
    try:
        body = json.loads(msg["data"])
        if body["state"] != "wait":
            return None
        x, y, yaw = (float(v) for v in body["spot"])
        px, py = (float(v) for v in body["place"])
        order = WaitOrder(str(body["map_id"]), (x, y, yaw), (px, py), str(body["waiting_for"]))
    except (KeyError, TypeError, ValueError, AttributeError):
        return None
    return order if _finite(x, y, yaw, px, py) else None


@dataclass(frozen=True)
class MappingNews:
    """The cloud's word on a robot's latched ``mapping`` topic: what happened (``event``:
    ``started``, ``saved``, ``stopped``, or ``not_mapping`` for camera frames streamed
    with no session) to its mapping session (None: it has none), and why."""

    session: int | None
    event: str
    reason: str = ""


def mapping_message(news: MappingNews) -> String:
    """``std_msgs/String`` on ``/r/mapping``: ``data`` is JSON, ``{"session", "event"}``
    and ``"reason"`` when there is one."""
    body: dict[str, Any] = {"session": news.session, "event": news.event}
    if news.reason:
        body["reason"] = news.reason
    return string_message(json.dumps(body))


def mapping_news_of(msg: Message) -> MappingNews | None:
    """The news in a ``mapping`` message; None for a message that is not one."""
    try:
        body = json.loads(msg["data"])
        session, event, reason = body["session"], body["event"], body.get("reason", "")
    except (KeyError, TypeError, ValueError, AttributeError):
        return None
    if not (session is None or type(session) is int) or not isinstance(event, str):
        return None
    return MappingNews(session, event, reason if isinstance(reason, str) else "")


def goal_of(msg: Message) -> Pose2D | None:
    """The target of a goal ``PoseStamped`` (``map_id`` = its frame), or None if the
    message has no usable pose or no frame."""
    pose = pose_of(msg)
    if pose is None or not pose.map_id or not _finite(pose.x, pose.y, pose.yaw):
        return None
    return pose


def initial_pose_of(msg: Message) -> tuple[Pose2D, NDArray[np.float64]] | None:
    """Pose and 3x3 covariance (x, y, yaw) of a ``PoseWithCovarianceStamped``; a missing
    or unusable covariance becomes a small default. None without a pose and a frame."""
    try:
        inner = msg["pose"]
        pose = goal_of({"header": msg.get("header", {}), "pose": inner["pose"]})
    except (KeyError, TypeError, AttributeError):
        return None
    if pose is None:
        return None
    return pose, _planar_covariance(inner.get("covariance"))


_DEFAULT_COVARIANCE = np.diag([0.25**2, 0.25**2, math.radians(15) ** 2])
"""Used when an initial pose comes without a covariance (rviz sends this order too)."""


def _planar_covariance(values: Any) -> NDArray[np.float64]:
    """The (x, y, yaw) block of a row-major 6x6 covariance."""
    try:
        full = np.asarray(values, np.float64).reshape(6, 6)
    except (TypeError, ValueError):
        return _DEFAULT_COVARIANCE.copy()
    planar = full[np.ix_(_PLANAR, _PLANAR)]
    if not np.isfinite(planar).all() or np.any(np.diag(planar) <= 0):
        return _DEFAULT_COVARIANCE.copy()
    return planar


def twist_of(msg: Message) -> tuple[float, float] | None:
    """``(linear.x, angular.z)`` of a ``geometry_msgs/Twist``; None unless both are finite
    numbers (a missing axis counts as 0)."""
    try:
        linear = float(msg.get("linear", {}).get("x", 0.0) or 0.0)
        angular = float(msg.get("angular", {}).get("z", 0.0) or 0.0)
    except (AttributeError, TypeError, ValueError):
        return None
    return (linear, angular) if math.isfinite(linear) and math.isfinite(angular) else None


def string_of(msg: Message) -> str | None:
    """Return the ``data`` of a ``std_msgs/String``, or None."""
    data = msg.get("data")
    return data if isinstance(data, str) else None


def _finite(*values: float) -> bool:
    return all(math.isfinite(v) for v in values)


def goal_live(msg: Message) -> bool:
    """Whether the newest goal of a ``GoalStatusArray`` is still under way (not finished
    for good); False for an empty or unreadable one."""
    statuses = msg.get("status_list")
    latest = statuses[-1] if isinstance(statuses, list) and statuses else None
    code = latest.get("status") if isinstance(latest, Mapping) else None
    if not isinstance(code, int) or code not in GoalStatus._value2member_map_:
        return False
    return not GoalStatus(code).terminal
