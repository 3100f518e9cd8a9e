"""A known room rendered for the visual mapping tests: its grid, camera frames of it, and
those frames as rosbridge image messages."""

from __future__ import annotations

from typing import Any

import cv2
import numpy as np

from benchmarks.visual_tracking import rendered
from cloudnav_core import messages
from cloudnav_core.camera import Intrinsics
from cloudnav_core.se2 import Pose
from maps.domain.visual_mapping import Frame

RESOLUTION = 0.05


def known_room() -> np.ndarray:
    """A 6 m x 4 m room, walls one cell thick, cell (0, 0) at the origin."""
    grid = np.zeros((80, 120), np.int8)
    grid[0, :] = grid[-1, :] = grid[:, 0] = grid[:, -1] = 100
    return grid


def frames(poses: list[Pose], first_stamp: float = 100.0) -> list[Frame]:
    return [
        Frame(first_stamp + 0.2 * index, image, depth, Intrinsics())
        for index, (image, depth) in enumerate(rendered(poses, 1))
    ]


def image_message(image: np.ndarray, stamp: float) -> dict[str, Any]:
    ok, jpeg = cv2.imencode(".jpg", image)
    assert ok
    return dict(messages.compressed_image("camera_optical_frame", jpeg.tobytes(), stamp))
