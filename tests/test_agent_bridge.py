"""What the ROS 1 and ROS 2 bridges share (``robots.agent.bridge``), without ROS: the
conversions, the drivers' readings behind the hardware seam, the stack's book."""

from __future__ import annotations

import threading
import time
from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest

from cloudnav_core.camera import CameraModel
from robots.agent.bridge import (
    DriverReadings,
    StackReadings,
    camera_model_of,
    full_covariance,
    image_of_raw,
    planar_covariance,
)


class Clock:
    """A monotonic clock the test moves."""

    def __init__(self) -> None:
        self.now = 100.0

    def __call__(self) -> float:
        return self.now


@pytest.fixture
def clock(monkeypatch: pytest.MonkeyPatch) -> Clock:
    moved = Clock()
    monkeypatch.setattr(time, "monotonic", moved)  # as the bridge reads it
    return moved


def test_a_frame_counts_until_it_is_older_than_a_second(clock: Clock) -> None:
    readings = DriverReadings(CameraModel())
    frame = np.full((480, 640), 200, dtype=np.uint8)
    readings.on_image(frame)
    clock.now += 0.9
    assert readings.image()[0, 0] == 200
    clock.now += 0.2  # the camera's frames stopped coming: no stale view of the tag
    assert readings.image().shape == (480, 640)
    assert not readings.image().any()


def test_the_covariance_keeps_x_y_and_yaw_of_the_six_by_six() -> None:
    planar = np.array([[0.04, 0.01, 0.0], [0.01, 0.09, 0.002], [0.0, 0.002, 0.01]])
    full = full_covariance(planar)
    assert len(full) == 36
    assert (full[0], full[7], full[35], full[1], full[11]) == pytest.approx(
        (0.04, 0.09, 0.01, 0.01, 0.002)
    )
    assert planar_covariance(full) == pytest.approx(planar)


def test_a_raw_rgb_image_is_read_as_bgr_and_a_short_one_is_refused() -> None:
    rgb = np.zeros((2, 3, 3), dtype=np.uint8)
    rgb[..., 0] = 255  # red
    bgr = image_of_raw("rgb8", 2, 3, rgb.tobytes())
    assert bgr[0, 0].tolist() == [0, 0, 255]
    with pytest.raises(ValueError, match="bytes for a 3x2"):
        image_of_raw("mono8", 2, 3, b"\x00" * 5)
    with pytest.raises(ValueError, match="unsupported"):
        image_of_raw("16UC1", 2, 3, b"\x00" * 12)


def test_an_uncalibrated_camera_info_leaves_the_default_camera() -> None:
    assert camera_model_of([0.0] * 9, 1280, 720) == CameraModel()
    calibrated = camera_model_of([910.0, 0, 641.5, 0, 905.0, 359.5, 0, 0, 1], 1280, 720)
    assert (calibrated.fx, calibrated.cy, calibrated.width) == (910.0, 359.5, 1280)


def test_the_stack_pose_counts_once_stamped_after_the_last_placement() -> None:
    book = StackReadings()
    book.map_id = "b/m"
    with pytest.raises(ValueError, match="not the map"):
        book.held("b/other")
    book.placed(10.0)
    book.on_pose(9.5, (1.0, 2.0, 0.0))
    assert book.pose() is None
    book.on_pose(10.5, (1.5, 2.0, 0.1))
    assert book.pose() == (1.5, 2.0, 0.1)


def test_driver_readings_give_odometry_and_scans_as_the_seam_wants() -> None:
    def odom(x: float) -> Any:
        orientation = SimpleNamespace(x=0.0, y=0.0, z=0.0, w=1.0)
        pose = SimpleNamespace(position=SimpleNamespace(x=x, y=0.0), orientation=orientation)
        twist = SimpleNamespace(linear=SimpleNamespace(x=0.2), angular=SimpleNamespace(z=0.1))
        return SimpleNamespace(
            header=SimpleNamespace(frame_id="odom"),
            child_frame_id="base_link",
            pose=SimpleNamespace(pose=pose, covariance=[0.0] * 36),
            twist=SimpleNamespace(twist=twist, covariance=[0.0] * 36),
        )

    scan = SimpleNamespace(angle_min=-1.0, angle_increment=0.5, ranges=[1.0, 2.0, 3.0, 4.0, 5.0])
    readings = DriverReadings(CameraModel())
    readings.ready(odom(1.0), scan)
    readings.on_odom(odom(2.0))
    assert readings.odom_pose == (2.0, 0.0, 0.0)
    assert readings.reported_velocity == (0.2, 0.1)
    assert readings.scan_angles == pytest.approx([-1.0, -0.5, 0.0, 0.5, 1.0])
    assert readings.odometry_message(3.0)["child_frame_id"] == "base_link"


def test_driver_readings_wait_for_the_first_odometry_and_scan_from_their_callbacks() -> None:
    # The ROS 2 drivers take the first readings from the subscriptions they keep, not from
    # short-lived ones destroyed while another thread spins the node.
    orientation = SimpleNamespace(x=0.0, y=0.0, z=0.0, w=1.0)
    pose = SimpleNamespace(position=SimpleNamespace(x=3.0, y=0.0), orientation=orientation)
    odom = SimpleNamespace(pose=SimpleNamespace(pose=pose))
    scan = SimpleNamespace(angle_min=-1.0, angle_increment=1.0, ranges=[1.0, 2.0, 3.0])
    readings = DriverReadings(CameraModel())
    assert not readings.wait_ready(0.01)  # nothing came
    readings.on_odom(odom)
    assert not readings.wait_ready(0.01)  # odometry alone is not enough
    callbacks = threading.Timer(0.05, readings.on_scan, args=(scan,))
    callbacks.start()
    assert readings.wait_ready(10.0)
    callbacks.join()
    assert readings.odom_pose == (3.0, 0.0, 0.0)
    assert readings.scan_angles == pytest.approx([-1.0, 0.0, 1.0])
