"""Camera frames and video stream requests, as web_video_server understands them.

A robot publishes ``sensor_msgs/CompressedImage`` (JPEG, base64 in JSON or bytes in CBOR);
``frame_from_message`` turns one into a ``Frame``. A viewer asks for
``/stream?topic=T&type=mjpeg|vp8|ros_compressed`` with web_video_server's parameters;
``parse_stream_request`` turns the query into a ``StreamRequest`` whose ``params`` say
which pipeline serves it: equal params share one pipeline (one re-encode, one encoder).

The errors below are the video relay's own; the HTTP views map each to one status.
No Django here: this module is part of the domain layer.
"""

from __future__ import annotations

import base64
import binascii
import time
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from cloudnav_core.times import stamp_seconds

from .names import canonical_type

MJPEG = "mjpeg"
VP8 = "vp8"
ROS_COMPRESSED = "ros_compressed"
STREAM_TYPES = (MJPEG, VP8, ROS_COMPRESSED)
SOURCE = "source"
"""The statistics' name for a camera's frames as published, before any relay."""
DEFAULT_TYPE = MJPEG

COMPRESSED_IMAGE = "sensor_msgs/CompressedImage"
COMPRESSED_VIDEO = "foxglove_msgs/CompressedVideo"
"""Foxglove's video message (``timestamp``, ``frame_id``, ``data``, ``format``): a camera
that encodes H.264 itself; its access units are relayed to WebRTC viewers as they are."""
CAMERA_TYPES = (COMPRESSED_IMAGE, COMPRESSED_VIDEO)
COMPRESSED_SUFFIX = "/compressed"
DEPTH_SUFFIX = "/compressedDepth"
"""ROS's ``compressedDepth`` transport: a ``CompressedImage`` too, but a depth map."""

# web_video_server's defaults: JPEG quality of a re-encode, and its libav (VP8) settings.
DEFAULT_QUALITY = 95
DEFAULT_BITRATE = 100_000
DEFAULT_QMIN = 10
DEFAULT_QMAX = 42
DEFAULT_GOP = 25
VP8_DEADLINES = ("realtime", "good", "best")
# Bounds a request cannot exceed: they keep one viewer from making the server encode huge
# frames or hold a long keyframe interval in memory.
MAX_SIDE = 4096
MAX_GOP = 300
MAX_BITRATE = 50_000_000


class VideoError(Exception):
    """Base of the video relay's errors."""


class UnknownStream(VideoError):
    """No such stream: an unknown ``type``, or a topic that is no robot's camera."""


class BadStreamParam(VideoError):
    """A query parameter is malformed or out of its range."""


class NotAuthenticated(VideoError):
    """No credential, or a robot token that matches no robot."""


class NotWatchable(VideoError):
    """A robot asked for a camera other than its own."""


class BadFrame(VideoError):
    """A published message is not a compressed image the relay can use."""


class NoFrame(VideoError):
    """No frame arrived in time (a snapshot of a silent camera)."""


@dataclass(frozen=True, slots=True)
class Frame:
    """One compressed camera image.

    ``stamp`` is the message's ``header.stamp`` in seconds (None without one);
    ``received`` is when the server took it, on the wall clock (``time.time``).
    """

    data: bytes
    format: str
    stamp: float | None
    received: float

    @property
    def content_type(self) -> str | None:
        return content_type_of(self.format)

    @property
    def is_h264(self) -> bool:
        return is_h264(self.format)

    @property
    def is_jpeg(self) -> bool:
        return self.content_type == "image/jpeg"

    @property
    def origin_time(self) -> float:
        """The frame's stamp, or when the server received it when it has none."""
        return self.stamp if self.stamp is not None else self.received


def is_camera(topic: str, type_name: str) -> bool:
    """True for a compressed image or video topic, but not a depth map sent through ROS's
    ``compressedDepth`` transport (no picture to watch)."""
    return canonical_type(type_name) in CAMERA_TYPES and not topic.endswith(DEPTH_SUFFIX)


def content_type_of(image_format: str) -> str | None:
    """Return the MIME type of a CompressedImage ``format`` (``jpeg``, ``bgr8; png
    compressed``...), or None for formats a browser cannot show (a ``compressedDepth``
    PNG sits behind a 12-byte header and holds millimetres, not a picture)."""
    lowered = image_format.lower()
    if "compresseddepth" in lowered:
        return None
    if "jpeg" in lowered or "jpg" in lowered:
        return "image/jpeg"
    if "png" in lowered:
        return "image/png"
    return None


def is_h264(image_format: str) -> bool:
    """True for an H.264 ``CompressedImage`` (``format`` ``h264``: Annex B access units),
    which the WebRTC relay passes through; the image relays cannot decode it."""
    return "h264" in image_format.lower()


def frame_from_message(msg: Mapping[str, Any], received: float | None = None) -> Frame:
    """Return the frame in a ``sensor_msgs/CompressedImage`` or
    ``foxglove_msgs/CompressedVideo`` message (only H.264 of the latter).

    ``data`` may be base64 text (rosbridge JSON), bytes (CBOR) or a list of byte values.
    Raises BadFrame when the data is missing or undecodable, or the format is neither an
    image format a browser can show nor H.264.
    """
    image_format = msg.get("format")
    if not isinstance(image_format, str) or not (
        content_type_of(image_format) or is_h264(image_format)
    ):
        raise BadFrame(f"unsupported image format {image_format!r}")
    data = _image_bytes(msg.get("data"))
    if not data:
        raise BadFrame("the image has no data")
    when = time.time() if received is None else received
    return Frame(data, image_format, stamp_seconds(msg), when)


def _image_bytes(data: Any) -> bytes:
    if isinstance(data, bytes | bytearray | memoryview):
        return bytes(data)
    if isinstance(data, str):
        try:
            return base64.b64decode(data, validate=True)
        except (binascii.Error, ValueError):
            raise BadFrame("image data is not valid base64") from None
    if isinstance(data, list):
        try:
            return bytes(data)
        except (TypeError, ValueError):
            raise BadFrame("image data is not a list of bytes") from None
    raise BadFrame(f"image data is a {type(data).__name__}")


# ---------------------------------------------------------------- stream requests


@dataclass(frozen=True, slots=True)
class ImageParams:
    """How each image is changed before it is sent: None everywhere means not at all.

    ``width``/``height`` of None keep the source's; as in web_video_server, giving only
    one of them keeps the other side as it is (the picture is stretched, not letterboxed).
    """

    quality: int | None = None
    width: int | None = None
    height: int | None = None
    invert: bool = False

    @property
    def untouched(self) -> bool:
        return (
            self.quality is None
            and self.width is None
            and self.height is None
            and not (self.invert)
        )


@dataclass(frozen=True, slots=True)
class Vp8Params:
    """libvpx settings of one VP8 encoder, named as web_video_server's query parameters."""

    bitrate: int = DEFAULT_BITRATE
    qmin: int = DEFAULT_QMIN
    qmax: int = DEFAULT_QMAX
    gop: int = DEFAULT_GOP
    deadline: str = "realtime"


@dataclass(frozen=True, slots=True)
class StreamParams:
    """What one pipeline produces; equal params on one topic share a pipeline."""

    type: str
    image: ImageParams = ImageParams()
    vp8: Vp8Params | None = None  # the encoder's settings (VP8 over WebM, and WebRTC)
    fps: int | None = None  # a cap on the frame rate sent (WebRTC); None: the camera's

    def label(self) -> str:
        """Return a short human-readable description, e.g. ``mjpeg q=90 320x-``."""
        parts = [self.type]
        image = self.image
        if image.quality is not None:
            parts.append(f"q={image.quality}")
        if image.width is not None or image.height is not None:
            parts.append(f"{image.width or '-'}x{image.height or '-'}")
        if image.invert:
            parts.append("inverted")
        if self.vp8 is not None:
            v = self.vp8
            parts.append(f"{v.bitrate // 1000}kbit/s q{v.qmin}-{v.qmax} gop={v.gop}")
        if self.fps is not None:
            parts.append(f"<={self.fps}fps")
        return " ".join(parts)


# The source size assumed when a stream keeps it (a camera's is known only from its frames).
ASSUMED_SOURCE = (1280, 720)
# What a VP8 pipeline holds per output pixel (libvpx's frames and buffers, the decoded
# camera frame, its scaled and I420 copies), and beside them. Measured as the resident
# growth of one encoder over 12 frames (tests/test_hostile_video_budget.py): 15 MiB at
# 640x480, 36 at 1280x720, 78 at 1920x1080, 567 at 4096x4096 (about 34 bytes a pixel
# plus 5 MiB, with a margin: 648 MiB at 4096x4096, where 8 I420 frames said 194).
VP8_BYTES_PER_PIXEL = 40
VP8_BYTES_BESIDE = 8 * 2**20


def encoder_memory(params: StreamParams) -> int:
    """Estimate the bytes an encoder of ``params`` holds: 0 for a stream that passes the
    camera's own JPEG through, else its frames at the size it sends."""
    image = params.image
    if params.vp8 is None and image.untouched:
        return 0
    width = image.width or ASSUMED_SOURCE[0]
    height = image.height or ASSUMED_SOURCE[1]
    if params.vp8 is not None:
        return width * height * VP8_BYTES_PER_PIXEL + VP8_BYTES_BESIDE
    return width * height * 3 * 2  # the decoded frame and its resized copy


@dataclass(frozen=True, slots=True)
class StreamRequest:
    """A parsed ``/stream`` (or ``/snapshot``) query: the topic as asked, and the params."""

    topic: str
    params: StreamParams


def parse_stream_request(
    query: Mapping[str, str], default_type: str = DEFAULT_TYPE
) -> StreamRequest:
    """Return the stream ``query`` asks for.

    Raises UnknownStream for a missing topic or an unknown ``type``, BadStreamParam for a
    malformed or out-of-range parameter.
    """
    topic = query.get("topic", "")
    if not topic:
        raise UnknownStream("no topic was given")
    kind = query.get("type") or default_type
    if kind not in STREAM_TYPES:
        raise UnknownStream(f"unknown stream type {kind!r}")
    if kind == ROS_COMPRESSED:
        # web_video_server relays the published bytes as they are, whatever else is asked.
        return StreamRequest(topic, StreamParams(ROS_COMPRESSED))
    image = _image_params(query, quality=kind == MJPEG)
    vp8 = _vp8_params(query) if kind == VP8 else None
    return StreamRequest(topic, StreamParams(kind, image, vp8))


def _image_params(query: Mapping[str, str], quality: bool) -> ImageParams:
    return ImageParams(
        quality=int_param(query, "quality", 1, 100) if quality else None,
        width=side_param(query, "width"),
        height=side_param(query, "height"),
        invert="invert" in query,
    )


def _vp8_params(query: Mapping[str, str]) -> Vp8Params:
    qmin = int_param(query, "qmin", 0, 63)
    qmax = int_param(query, "qmax", 0, 63)
    params = Vp8Params(
        bitrate=int_param(query, "bitrate", 1000, MAX_BITRATE) or DEFAULT_BITRATE,
        qmin=DEFAULT_QMIN if qmin is None else qmin,
        qmax=DEFAULT_QMAX if qmax is None else qmax,
        gop=int_param(query, "gop", 1, MAX_GOP) or DEFAULT_GOP,
        deadline=query.get("quality") or "realtime",
    )
    if params.qmin > params.qmax:
        raise BadStreamParam(f"qmin {params.qmin} is above qmax {params.qmax}")
    if params.deadline not in VP8_DEADLINES:
        raise BadStreamParam(f"VP8 quality must be one of {', '.join(VP8_DEADLINES)}")
    return params


def side_param(query: Mapping[str, str], name: str) -> int | None:
    """A width or height: absent, empty, 0 or -1 (web_video_server's "as the source") is None."""
    raw = query.get(name, "")
    if raw.strip() in {"", "-1", "0"}:
        return None
    return int_param(query, name, 1, MAX_SIDE)


def int_param(query: Mapping[str, str], name: str, low: int, high: int) -> int | None:
    raw = query.get(name)
    if raw is None or raw.strip() == "":
        return None
    try:
        value = int(raw)
    except ValueError:
        raise BadStreamParam(f"{name} must be an integer, not {raw!r}") from None
    if not low <= value <= high:
        raise BadStreamParam(f"{name} must be between {low} and {high}, not {value}")
    return value


def camera_topic_candidates(topic: str) -> list[str]:
    """Return the topics a ``topic`` parameter may mean, most specific first.

    web_video_server takes the image's base topic and reads ``<topic>/compressed`` for
    ``ros_compressed``; the CloudNav UI names the compressed topic itself. Both work.
    """
    base = topic.rstrip("/")
    if base.endswith(COMPRESSED_SUFFIX):
        return [base]
    return [base + COMPRESSED_SUFFIX, base]
