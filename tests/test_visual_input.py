"""What robots send the visual map, read before anything costly is done with it: a JPEG
whose decoding would cost seconds is refused from its bytes alone, and sizes, poses and
cameras no robot has are refused with the field at fault (issue 23 points 13 and 16)."""

from __future__ import annotations

import base64
import io
import math
import time
from typing import Any

import numpy as np
import pytest
from PIL import Image as PILImage

from cloudnav_core.camera import Intrinsics, Mount
from cloudnav_core.messages import depth_image as raw_depth_message
from maps.domain.keyframes import FeatureExtractor, Keyframe
from maps.domain.visual_input import (
    MAX_JPEG_SCANS,
    depth_image,
    grey_image,
    intrinsics_of,
    jpeg_scans,
    planar_pose,
)
from maps.domain.vocabulary import default_vocabulary
from maps.exceptions import KeyframeError
from robots.agent.hardware import encode_jpeg
from robots.agent.sim.camera import Camera
from robots.agent.sim.world import demo_world
from tests.support.keyframe_images import progressive_jpeg

PIXELS = 1280 * 960


def message(data: bytes) -> dict[str, Any]:
    return {"format": "jpeg", "data": base64.b64encode(data).decode()}


def test_a_jpeg_of_many_scans_is_refused_before_it_is_decoded() -> None:
    attack = progressive_jpeg(50_000)
    assert jpeg_scans(attack) == 50_000
    started = time.process_time()
    with pytest.raises(KeyframeError, match="50000 scans") as refused:
        grey_image(message(attack), PIXELS, "images[0]")
    # Decoding it takes about 14 s of CPU here; reading its header and counting, about 1 ms.
    assert time.process_time() - started < 0.5
    assert refused.value.field == "images[0]"


def test_a_jpeg_of_as_many_scans_as_allowed_is_decoded() -> None:
    pixels = grey_image(message(progressive_jpeg(MAX_JPEG_SCANS)), PIXELS)
    assert pixels.shape == (480, 640)


def test_the_robots_own_jpegs_and_an_ordinary_progressive_one_are_read() -> None:
    image = Camera(demo_world(seed=0)).render((5.0, 23.2, 0.0))
    assert jpeg_scans(encode_jpeg(image)) == 1
    out = io.BytesIO()
    PILImage.fromarray(image).save(out, "JPEG", progressive=True)
    assert 1 < jpeg_scans(out.getvalue()) <= 10
    assert grey_image(message(out.getvalue()), PIXELS).shape == image.shape


@pytest.mark.parametrize(
    ("height", "width", "step"), [(-480, -640, -1280), (-480, 640, 1280), (0, 640, 1280)]
)
def test_a_raw_depth_image_of_negative_or_no_size_is_refused(
    height: int, width: int, step: int
) -> None:
    msg = raw_depth_message("camera", np.ones((480, 640), np.float32), 1.0)
    msg = {**msg, "height": height, "width": width, "step": step}
    with pytest.raises(KeyframeError) as refused:
        depth_image(msg, (480, 640), PIXELS)
    assert refused.value.field == "depth"


@pytest.mark.parametrize(
    "pose",
    [
        {"x": 1e308, "y": 3.0, "yaw": 0.0},
        {"x": 1.0, "y": -1e308, "yaw": 0.0},
        {"x": 1.0, "y": 3.0, "yaw": 1e308},
    ],
)
def test_a_pose_no_robot_could_have_is_refused(pose: dict[str, float]) -> None:
    with pytest.raises(KeyframeError, match="within") as refused:
        planar_pose(pose)
    assert refused.value.field == "pose"


@pytest.mark.parametrize(
    "k",
    [
        [1e-300, 0, 319.5, 0, 525, 239.5, 0, 0, 1],
        [525, 0, 319.5, 0, 1e308, 239.5, 0, 0, 1],
        [525, 0, 1e308, 0, 525, 239.5, 0, 0, 1],
        [525, 0, 319.5, 0, 525, -1e308, 0, 0, 1],
    ],
)
def test_a_camera_no_robot_could_have_is_refused(k: list[float]) -> None:
    with pytest.raises(KeyframeError) as refused:
        intrinsics_of({"K": k}, (480, 640))
    assert refused.value.field == "camera_info"


def test_a_keyframe_whose_points_are_not_finite_is_refused() -> None:
    """A camera built past the request's checks (the extractor is also the benchmarks'
    and the tests'): its points would be infinite, and no keyframe is made of them."""
    pose = (5.0, 23.2, 0.0)
    image, depth = Camera(demo_world(seed=0)).capture(pose)
    assert depth is not None
    extractor = FeatureExtractor(default_vocabulary())
    with pytest.raises(KeyframeError, match="not all finite"):
        extractor.keyframe(image, depth, pose, Intrinsics(cx=1e308), Mount())


def test_a_stored_keyframe_whose_points_are_not_finite_is_not_read() -> None:
    points = np.array([[1.0, 2.0, 0.3], [math.inf, 2.0, 0.3]], np.float32)
    stored = Keyframe((1.0, 2.0, 0.0), np.zeros((2, 32), np.uint8), points, np.ones(4, np.float32))
    with pytest.raises(KeyframeError, match="not finite") as refused:
        Keyframe.from_bytes(stored.to_bytes())
    assert refused.value.field == "keyframe"
