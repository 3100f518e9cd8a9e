"""The simulated walls carry stable, varied texture a feature detector finds; the camera
gives a registered depth image; both go out as ROS messages."""

from __future__ import annotations

import math

import cv2
import numpy as np

from cloudnav_core.camera import CameraModel
from cloudnav_core.messages import camera_info, depth_image, depth_of
from robots.agent.perception import TagDetector, pinhole_calibration
from robots.agent.sim.camera import Camera
from robots.agent.sim.world import demo_world

CORRIDOR_A = (5.0, 23.2, 0.4)  # looking east along Corridor A, towards its north wall
ATRIUM_1 = (20.0, 22.0, 2.0)


def orb_features(image: np.ndarray) -> int:
    return len(cv2.ORB.create(1000).detect(image))


def test_orb_finds_texture_on_the_walls_everywhere_it_looks() -> None:
    camera = Camera(demo_world())
    for pose in (CORRIDOR_A, ATRIUM_1, (12.0, 23.0, -math.pi / 2)):
        assert orb_features(camera.render(pose)) >= 300, pose


def test_the_walls_look_the_same_for_the_same_seed_and_differ_by_seed_and_building() -> None:
    def walls(**kw: object) -> np.ndarray:
        return Camera(demo_world(**kw), noise_sigma=0.0, blur_sigma=0.0).render(CORRIDOR_A)  # type: ignore[arg-type]

    same = walls(seed=3)
    np.testing.assert_array_equal(same, walls(seed=3))
    assert np.abs(same.astype(int) - walls(seed=4)).mean() > 10
    assert np.abs(same.astype(int) - walls(seed=3, building_code="other_2")).mean() > 10


def test_the_depth_image_is_registered_to_the_colour_image() -> None:
    camera = Camera(demo_world(), noise_sigma=0.0)
    model = CameraModel()
    x, y, _ = CORRIDOR_A
    facing_north = (x, y, math.pi / 2)  # Corridor A's north wall face is at y = 24.4
    image, depth = camera.capture(facing_north)
    assert depth is not None
    assert depth.shape == image.shape == (model.height, model.width)
    assert depth.dtype == np.float32
    centre = float(depth[int(model.cy), int(model.cx)])
    assert abs(centre - (24.4 - y - model.mount_x)) < 0.03
    # The floor in the bottom row lies where the ray through it meets the floor plane.
    assert abs(float(depth[-1, 320]) - model.fy * model.mount_height / (479 - model.cy)) < 1e-3


def test_tags_are_still_detected_on_the_textured_walls() -> None:
    world = demo_world(seed=7)
    for tag in world.tags[:6]:
        pose = (tag.x + 0.6 * math.cos(tag.yaw), tag.y + 0.6 * math.sin(tag.yaw), tag.yaw + math.pi)
        eye_back = (pose[0] - 0.05 * math.cos(pose[2]), pose[1] - 0.05 * math.sin(pose[2]), pose[2])
        found = TagDetector().detect(Camera(world).render(eye_back))
        assert tag.marker_id in [d.marker_id for d in found], tag.marker_id
        assert all(d.marker_id in {t.marker_id for t in world.tags} for d in found)


def test_depth_and_camera_info_messages_round_trip() -> None:
    _, depth = Camera(demo_world()).capture(CORRIDOR_A)
    assert depth is not None
    message = depth_image("camera_optical_frame", depth, 3.0)
    assert message["encoding"] == "16UC1"
    assert message["step"] == 1280
    back = depth_of(message, max_pixels=640 * 480)
    assert back is not None
    finite = np.isfinite(depth) & (depth < 60)
    assert np.nanmax(np.abs(back[finite] - depth[finite])) <= 0.0006
    assert depth_of(message, max_pixels=1000) is None
    assert depth_of({**message, "data": message["data"][:-8]}, 640 * 480) is None
    info = camera_info("camera_optical_frame", pinhole_calibration(CameraModel()), 3.0)
    assert info["K"] == [525.0, 0.0, 319.5, 0.0, 525.0, 239.5, 0.0, 0.0, 1.0]
    assert info["P"] == [525.0, 0.0, 319.5, 0.0, 0.0, 525.0, 239.5, 0.0, 0.0, 0.0, 1.0, 0.0]
    assert (info["width"], info["height"], info["header"]["frame_id"]) == (
        640,
        480,
        "camera_optical_frame",
    )
