"""Reading what robots send the visual map: images, depth, camera parameters and poses,
as rosbridge JSON (``sensor_msgs/CompressedImage``; depth as ROS's ``compressedDepth``
or a raw ``sensor_msgs/Image``; ``sensor_msgs/CameraInfo``). Every reader raises
KeyframeError with a sentence for the sender; nothing is decoded past the pixel limit
(the size is read from the header first).

Nothing here imports Django.
"""

from __future__ import annotations

import base64
import binascii
import io
import math
import warnings
from collections.abc import Mapping
from typing import Any

import cv2
import numpy as np
from PIL import Image as PILImage

from cloudnav_core.camera import Intrinsics
from cloudnav_core.messages import depth_of
from cloudnav_core.times import parse_stamp
from maps.domain.keyframes import Depth, Image
from maps.exceptions import KeyframeError

MAX_IMAGES = 8
"""Images one relocalisation request may carry."""
MAX_JPEG_SCANS = 32
"""Scans a JPEG may have. A progressive JPEG's decoder passes over every coefficient of
the image once per scan (about 0.3 ms per scan at 640x480 here), so its cost is its
pixels times its scans: 50,000 scans of a 640x480 image took 14 s of CPU. Encoders write
1 scan (baseline) or about 10 (progressive: libjpeg's default script; 6 for grey)."""
MAX_COORDINATE = 1e6
"""Metres: a pose farther than this from its map's origin is no robot's."""
MIN_FOCAL, MAX_FOCAL = 1.0, 100_000.0
"""Pixels: focal lengths outside these belong to no camera (a pinhole's field of view
from nearly 180 degrees to a few thousandths of one at 640 px)."""


def grey_image(msg: Any, max_pixels: int, field: str = "image") -> Image:
    """The grey pixels of a ``CompressedImage``-shaped object (JPEG or PNG, base64)."""
    data, (width, height) = _checked_image(msg, max_pixels, field)
    pixels = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_GRAYSCALE)
    if pixels is None or pixels.shape != (height, width):
        raise KeyframeError(field, "the image is truncated or corrupt")
    return np.asarray(pixels, np.uint8)


def quarter_colour_image(msg: Any, max_pixels: int, field: str = "image") -> Image:
    """The RGB pixels of a ``CompressedImage``-shaped object at a quarter of its width
    and height (a JPEG's decoder scales it while decoding: cheap), for colouring a
    keyframe's cloud."""
    data, _ = _checked_image(msg, max_pixels, field)
    pixels = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_REDUCED_COLOR_4)
    if pixels is None:
        raise KeyframeError(field, "the image is truncated or corrupt")
    return np.asarray(cv2.cvtColor(pixels, cv2.COLOR_BGR2RGB), np.uint8)


def _checked_image(msg: Any, max_pixels: int, field: str) -> tuple[bytes, tuple[int, int]]:
    """The bytes of an image message and its (width, height), read from its header and
    checked against the pixel limit and the JPEG scan limit before anything is decoded."""
    if not isinstance(msg, Mapping) or not isinstance(msg.get("data"), str):
        raise KeyframeError(field, "a sensor_msgs/CompressedImage with base64 'data' is required")
    try:
        data = base64.b64decode(msg["data"], validate=True)
    except (binascii.Error, ValueError):
        raise KeyframeError(field, "'data' is not base64") from None
    width, height = _size(data, field)
    if width * height > max_pixels:
        raise KeyframeError(
            field, f"{width}x{height} is more than the {max_pixels} pixels an image may have"
        )
    scans = jpeg_scans(data)
    if scans > MAX_JPEG_SCANS:
        raise KeyframeError(field, f"a JPEG of {scans} scans; at most {MAX_JPEG_SCANS} are decoded")
    return data, (width, height)


def _size(data: bytes, field: str) -> tuple[int, int]:
    """Width and height from the header alone; raises for anything not a JPEG or PNG."""
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error", PILImage.DecompressionBombWarning)
            with PILImage.open(io.BytesIO(data)) as image:
                if image.format not in {"JPEG", "PNG"}:
                    raise KeyframeError(field, "only JPEG and PNG images are taken")
                return image.size
    except KeyframeError:
        raise
    except (OSError, ValueError, PILImage.DecompressionBombError, Warning):
        raise KeyframeError(field, "not an image") from None


def jpeg_scans(data: bytes) -> int:
    """How many scans (start-of-scan markers) a JPEG has at most; 0 for a PNG. Inside a
    scan's entropy-coded data every 0xFF byte is followed by 0x00 or a marker, so each
    0xFF 0xDA is a scan's start or lies in a metadata segment: the count is never low."""
    return data.count(b"\xff\xda") if data.startswith(b"\xff\xd8") else 0


def depth_image(msg: Any, shape: tuple[int, ...], max_pixels: int) -> Depth:
    """Metres of a depth image registered to an image of ``shape``: a
    ``sensor_msgs/CompressedImage`` of ROS's ``compressedDepth`` transport (``16UC1;
    compressedDepth png``, what robots send) or a raw ``sensor_msgs/Image`` (``16UC1`` mm
    or ``32FC1`` m); raises unless it is one and matches that size."""
    if not isinstance(msg, Mapping):
        raise KeyframeError("depth", "a sensor_msgs/CompressedImage or Image is required")
    depth = depth_of(msg, max_pixels)
    if depth is None:
        raise KeyframeError(
            "depth",
            "a compressedDepth sensor_msgs/CompressedImage ('16UC1; compressedDepth "
            "png' or '32FC1; compressedDepth png') or a 16UC1 (millimetres) or 32FC1 "
            "(metres) sensor_msgs/Image whose data fills the image, at most "
            f"{max_pixels} pixels, is required",
        )
    if depth.shape != shape[:2]:
        raise KeyframeError(
            "depth",
            f"{depth.shape[1]}x{depth.shape[0]} does not match the "
            f"{shape[1]}x{shape[0]} image it must be registered to",
        )
    return depth


def finite_depth(msg: Any) -> None:
    """Raise KeyframeError when a raw ``32FC1`` depth image holds readings that are not
    finite numbers (NaN, inf): a mapping session takes 0 for "no reading", so a
    non-finite value is a fault of the sender, never silently a hole. The other forms
    (millimetres in 16 bits, compressedDepth PNGs) cannot hold one."""
    if not isinstance(msg, Mapping) or msg.get("encoding") != "32FC1":
        return
    try:
        data = base64.b64decode(str(msg.get("data", "")), validate=True)
    except (binascii.Error, ValueError):
        return  # depth_image says what is wrong with it
    kind = ">f4" if msg.get("is_bigendian") else "<f4"
    values = np.frombuffer(data[: len(data) // 4 * 4], kind)
    bad = int((~np.isfinite(values)).sum())
    if bad:
        raise KeyframeError(
            "depth", f"{bad} readings are not finite numbers: send 0 where there is no reading"
        )


def stamp_of(msg: Any, field: str) -> float:
    """``header.stamp`` of a message in seconds; raises KeyframeError without one."""
    header = msg.get("header") if isinstance(msg, Mapping) else None
    value = header.get("stamp") if isinstance(header, Mapping) else None
    try:
        sec, nanosec = parse_stamp(value if isinstance(value, Mapping) else {})
    except ValueError:
        raise KeyframeError(field, "header.stamp (sec, nanosec) is required") from None
    return sec + nanosec / 1e9


def intrinsics_of(msg: Any, shape: tuple[int, ...]) -> Intrinsics:
    """The camera of a ``CameraInfo``-shaped object (only ``K`` is read), or the robots'
    default camera when there is none; the image's size wins."""
    height, width = shape[:2]
    if msg is None:
        default = Intrinsics()
        if (width, height) != (default.width, default.height):
            raise KeyframeError(
                "camera_info",
                f"required for a {width}x{height} image (the default camera "
                f"is {default.width}x{default.height})",
            )
        return default
    if not isinstance(msg, Mapping) or not isinstance(msg.get("K"), list):
        raise KeyframeError("camera_info", "a sensor_msgs/CameraInfo with 'K' is required")
    try:
        k = [float(v) for v in msg["K"]]
    except (TypeError, ValueError):
        raise KeyframeError("camera_info", "'K' must be numbers") from None
    return _intrinsics_from_k(k, width, height)


def _intrinsics_from_k(k: list[float], width: int, height: int) -> Intrinsics:
    """From a ``CameraInfo``'s row-major ``K``; raises KeyframeError if it is not one."""
    if len(k) != 9 or not all(math.isfinite(v) for v in k):
        raise KeyframeError("camera_info", "K must be 9 finite numbers")
    if not (MIN_FOCAL <= k[0] <= MAX_FOCAL and MIN_FOCAL <= k[4] <= MAX_FOCAL):
        raise KeyframeError(
            "camera_info", f"K's focal lengths must be within [{MIN_FOCAL}, {MAX_FOCAL}] px"
        )
    if not (0 <= k[2] <= width and 0 <= k[5] <= height):
        raise KeyframeError("camera_info", "K's principal point must lie in the image")
    return Intrinsics(width, height, float(k[0]), float(k[4]), float(k[2]), float(k[5]))


def planar_pose(value: Any) -> tuple[float, float, float]:
    """``{x, y, yaw}`` as finite numbers."""
    try:
        pose = float(value["x"]), float(value["y"]), float(value["yaw"])
    except (KeyError, TypeError, ValueError):
        raise KeyframeError("pose", "{x, y, yaw} in metres and radians is required") from None
    if not all(math.isfinite(v) for v in pose):
        raise KeyframeError("pose", "x, y and yaw must be finite")
    if not all(abs(v) <= MAX_COORDINATE for v in pose):
        raise KeyframeError("pose", f"x, y and yaw must be within {MAX_COORDINATE:.0e}")
    return pose


def image_list(value: Any) -> list[Any]:
    """The ``images`` of a relocalisation request: 1 to ``MAX_IMAGES`` of them."""
    if not isinstance(value, list) or not 1 <= len(value) <= MAX_IMAGES:
        raise KeyframeError(
            "images", f"a list of 1 to {MAX_IMAGES} CompressedImage objects is required"
        )
    return value
