"""ROS messages as the server and the robot both write them (``cloudnav_core.messages``)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from cloudnav_core.messages import (
    covariance_6x6,
    odometry,
    path_of,
    ros_time,
    twist_2d,
    yaw_of,
)
from cloudnav_core.times import now_stamp, stamp


def test_a_wall_clock_stamp_keeps_its_nanoseconds():
    assert ros_time(1_700_000_000.25) == {"sec": 1_700_000_000, "nanosec": 250_000_000}
    assert ros_time(-1.5) == {"sec": -2, "nanosec": 500_000_000}


def test_a_stamp_that_rounds_up_carries_into_the_seconds():
    assert ros_time(41.9999999999) == {"sec": 42, "nanosec": 0}
    assert now_stamp(clock=lambda: 41.9999999999) == stamp(42, 0)


def test_a_path_keeps_the_poses_and_the_stamp_it_is_given():
    when = stamp(7, 5)
    path = path_of("b/M", [(1.0, 2.0, 0.0), (3.0, 4.0, math.pi / 2)], when)
    assert path["header"] == {"stamp": when, "frame_id": "b/M"}
    assert [p["header"] for p in path["poses"]] == [path["header"]] * 2
    assert path["poses"][0]["pose"]["orientation"] == {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}
    assert yaw_of(path["poses"][1]["pose"]["orientation"]) == pytest.approx(math.pi / 2)


def test_a_planar_covariance_fills_x_y_and_yaw_of_the_six_by_six():
    planar = np.array([[1.0, 2.0, 3.0], [2.0, 4.0, 5.0], [3.0, 5.0, 6.0]])
    full = np.array(covariance_6x6(planar)).reshape(6, 6)
    assert full[np.ix_([0, 1, 5], [0, 1, 5])].tolist() == planar.tolist()
    assert np.count_nonzero(full) == 9


def test_odometry_carries_the_pose_in_its_frame_and_the_velocity_in_the_robots():
    message = odometry(
        "odom",
        "base_footprint",
        2.5,
        pose=(1.0, 2.0, 0.0),
        pose_covariance=np.diag([0.1, 0.1, 0.2]),
        velocity=(0.3, -0.4),
        velocity_covariance=np.diag([1e-4, 1e-4, 1e-4]),
    )
    assert message["header"] == {"stamp": {"sec": 2, "nanosec": 500_000_000}, "frame_id": "odom"}
    assert message["child_frame_id"] == "base_footprint"
    assert message["pose"]["pose"]["position"] == {"x": 1.0, "y": 2.0, "z": 0.0}
    assert message["pose"]["covariance"][35] == 0.2
    assert message["twist"]["twist"] == twist_2d(0.3, -0.4)
