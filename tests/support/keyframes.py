"""Keyframes as robots send them, and the survey of Corridor A that the visual server
tests post."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from cloudnav_core.messages import (
    compressed_depth,
    compressed_image,
)
from robots.agent.hardware import encode_jpeg
from robots.agent.sim.camera import Camera

SURVEY = [
    (x, y, yaw) for x in np.arange(4.0, 12.0, 0.5) for y in (22.6, 23.8) for yaw in (0.0, math.pi)
]
WAKE_UP = (7.3, 23.1, 0.15)


def keyframe_body(camera: Camera, pose: tuple[float, float, float]) -> dict[str, Any]:
    """A keyframe as robots send it: JPEG, depth as ROS's compressedDepth, pose."""
    image, depth = camera.capture(pose)
    assert depth is not None
    return {
        "image": compressed_image("camera", encode_jpeg(image, 90), 1.0),
        "depth": compressed_depth("camera", depth, 1.0),
        "pose": {"x": pose[0], "y": pose[1], "yaw": pose[2]},
    }
