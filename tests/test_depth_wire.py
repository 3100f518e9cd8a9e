"""Depth on the wire as ROS's ``compressed_depth_image_transport`` sends it: a
``sensor_msgs/CompressedImage`` whose data is a 12-byte header and a 16-bit PNG, read
back exactly (millimetres), a few kB where the raw ``sensor_msgs/Image`` is 800 kB.
Anything else in that form is refused before a pixel is inflated."""

from __future__ import annotations

import base64
import json
import struct
from typing import Any

import cv2
import numpy as np
import pytest

from cloudnav_core.messages import (
    COMPRESSED_DEPTH_FORMAT,
    compressed_depth,
    depth_image,
    depth_of,
)
from robots.agent.sim.camera import Camera
from robots.agent.sim.world import demo_world
from telemetry.domain.video import content_type_of, is_camera

CORRIDOR_A = (6.0, 23.2, 0.2)
PIXELS = 640 * 480


@pytest.fixture(scope="module")
def depth() -> np.ndarray:
    _, depth = Camera(demo_world(seed=0)).capture(CORRIDOR_A)
    assert depth is not None
    return depth


def payload(message: Any) -> bytes:
    return base64.b64decode(message["data"])


def with_payload(message: Any, data: bytes, **changes: Any) -> dict[str, Any]:
    return {**message, "data": base64.b64encode(data).decode("ascii"), **changes}


def test_it_writes_ros_compressed_depth_a_header_then_a_16_bit_png(depth: np.ndarray) -> None:
    message = compressed_depth("camera_optical_frame", depth, 3.0)
    data = payload(message)
    assert message["format"] == COMPRESSED_DEPTH_FORMAT == "16UC1; compressedDepth png"
    assert struct.unpack("<iff", data[:12]) == (0, 0.0, 0.0)
    millimetres = cv2.imdecode(np.frombuffer(data[12:], np.uint8), cv2.IMREAD_UNCHANGED)
    raw = np.frombuffer(payload(depth_image("camera", depth, 3.0)), "<u2").reshape(480, 640)
    assert millimetres is not None
    assert millimetres.dtype == np.uint16
    assert np.array_equal(millimetres, raw)


def test_it_reads_back_exactly_what_the_raw_image_carries(depth: np.ndarray) -> None:
    compressed = depth_of(compressed_depth("camera", depth, 3.0), PIXELS)
    raw = depth_of(depth_image("camera", depth, 3.0), PIXELS)
    assert compressed is not None
    assert raw is not None
    assert np.array_equal(np.isnan(compressed), np.isnan(raw))
    assert np.array_equal(compressed[~np.isnan(raw)], raw[~np.isnan(raw)])


def test_it_is_a_small_fraction_of_the_raw_image(depth: np.ndarray) -> None:
    compressed = len(json.dumps(compressed_depth("camera", depth, 3.0)))
    raw = len(json.dumps(depth_image("camera", depth, 3.0)))
    assert raw > 800_000
    assert compressed < raw / 20


def test_it_reads_32fc1_compressed_depth_as_ros_quantises_it() -> None:
    metres = np.linspace(0.5, 6.0, 40 * 30, dtype=np.float32).reshape(30, 40)
    metres[0, :5] = np.nan  # no reading: inverse depth 0
    quant_a, quant_b = 100.0, 10.0  # ROS's defaults: depth = A / (value - B)
    inverse = np.where(np.isnan(metres), 0, np.rint(quant_a / metres + quant_b)).astype(np.uint16)
    png = cv2.imencode(".png", inverse)[1].tobytes()
    message = {
        "header": {"stamp": {"sec": 0, "nanosec": 0}, "frame_id": "camera"},
        "format": "32FC1; compressedDepth png",
        "data": base64.b64encode(struct.pack("<iff", 0, quant_a, quant_b) + png).decode(),
    }
    back = depth_of(message, PIXELS)
    assert back is not None
    assert np.isnan(back[0, :5]).all()
    # One step of inverse depth near 6 m (value 26.7) is about 0.22 m.
    assert np.nanmax(np.abs(back - metres)) < 0.2


def test_the_older_spelling_of_the_format_is_read(depth: np.ndarray) -> None:
    message = {**compressed_depth("camera", depth, 3.0), "format": "16UC1; compressedDepth"}
    assert depth_of(message, PIXELS) is not None


def test_it_refuses_more_pixels_than_allowed(depth: np.ndarray) -> None:
    assert depth_of(compressed_depth("camera", depth, 3.0), max_pixels=1000) is None


def png_instead(message: Any, png: bytes) -> dict[str, Any]:
    return with_payload(message, payload(message)[:12] + png)


@pytest.mark.parametrize(
    "spoil",
    [
        pytest.param(lambda m: with_payload(m, payload(m)[: len(payload(m)) // 2]), id="truncated"),
        pytest.param(lambda m: with_payload(m, payload(m)[:20]), id="header only"),
        pytest.param(lambda m: {**m, "data": "!!"}, id="not base64"),
        pytest.param(lambda m: {**m, "format": "16UC1; compressedDepth rvl"}, id="rvl"),
        pytest.param(lambda m: {**m, "format": "jpeg"}, id="a colour format"),
        pytest.param(lambda m: {**m, "format": "8UC1; compressedDepth png"}, id="8UC1"),
        pytest.param(
            lambda m: png_instead(m, cv2.imencode(".png", np.zeros((4, 4), np.uint8))[1].tobytes()),
            id="an 8-bit png",
        ),
        pytest.param(
            lambda m: png_instead(m, cv2.imencode(".jpg", np.zeros((4, 4)))[1].tobytes()),
            id="a jpeg",
        ),
    ],
)
def test_it_refuses_what_is_not_compressed_depth(depth: np.ndarray, spoil: Any) -> None:
    assert depth_of(spoil(compressed_depth("camera", depth, 3.0)), PIXELS) is None


def test_a_depth_topic_is_no_camera_to_watch() -> None:
    depth = "/r1/camera/depth/image/compressedDepth"
    assert not is_camera(depth, "sensor_msgs/CompressedImage")
    assert is_camera("/r1/camera/image/compressed", "sensor_msgs/CompressedImage")
    assert content_type_of(COMPRESSED_DEPTH_FORMAT) is None
    assert content_type_of("bgr8; png compressed bgr8") == "image/png"
