"""ROS 1 serialisation of rosbridge JSON (compiled per type): the bytes ``rosbags`` reads
back to the values sent and writes again identically, with rosbridge's conventions."""

from __future__ import annotations

import base64
import math
from typing import Any

import pytest

from telemetry.domain import ros1

ODOM = {
    "header": {"seq": 7, "stamp": {"sec": 1_800_000_000, "nanosec": 5}, "frame_id": "odom"},
    "child_frame_id": "base_link",
    "pose": {
        "pose": {"position": {"x": 1.5, "y": -2.0}, "orientation": {"z": 0.6, "w": 0.8}},
        "covariance": [i / 10 for i in range(36)],
    },
    "twist": {"twist": {"linear": {"x": 0.3}, "angular": {"z": -0.5}}, "covariance": [0] * 36},
}
PATH = {
    "header": {"frame_id": "b/Hall"},
    "poses": [
        {"header": {"frame_id": "b/Hall"}, "pose": {"position": {"x": float(i), "y": 1.0}}}
        for i in range(3)
    ],
}
LOG = {"level": 8, "name": "goal_aborted", "msg": "no path", "topics": ["goal=g7", "actor=é"]}
STATUS = {"status_list": [{"goal_id": {"id": "g1"}, "status": 3, "text": "done"}]}


def round_trip(type_name: str, msg: dict) -> Any:
    data = ros1.encode(type_name, msg)
    decoded = ros1.decode(type_name, data)
    store = ros1._store()
    again = bytes(store.serialize_ros1(decoded, ros1.store_name(type_name)))
    assert again == data  # rosbags writes the same bytes from what it read
    return decoded


def test_nested_messages_fixed_arrays_and_strings_read_back_as_sent():
    odom = round_trip("nav_msgs/Odometry", ODOM)
    assert (odom.header.seq, odom.header.stamp.sec, odom.header.stamp.nanosec) == (
        7,
        1_800_000_000,
        5,
    )
    assert (odom.header.frame_id, odom.child_frame_id) == ("odom", "base_link")
    assert odom.pose.pose.position.x == 1.5
    assert odom.pose.pose.orientation.w == 0.8
    assert list(odom.pose.covariance) == pytest.approx([i / 10 for i in range(36)])
    assert odom.twist.twist.angular.z == -0.5


def test_sequences_of_messages_and_of_strings_read_back_as_sent():
    path = round_trip("nav_msgs/Path", PATH)
    assert [p.pose.position.x for p in path.poses] == [0.0, 1.0, 2.0]
    log = round_trip("rosgraph_msgs/Log", LOG)
    assert (log.level, log.name, log.msg, log.topics) == (
        8,
        "goal_aborted",
        "no path",
        LOG["topics"],
    )
    status = round_trip("actionlib_msgs/GoalStatusArray", STATUS)
    assert (status.status_list[0].goal_id.id, status.status_list[0].status) == ("g1", 3)


def test_rosbridge_conventions_nulls_old_time_names_base64_and_missing_fields():
    scan = round_trip(
        "sensor_msgs/LaserScan",
        {"header": {"stamp": {"secs": 3, "nsecs": 4}}, "range_max": None, "ranges": [1.5, None]},
    )
    assert (scan.header.stamp.sec, scan.header.stamp.nanosec) == (3, 4)
    assert math.isnan(scan.range_max)
    assert scan.ranges[0] == 1.5
    assert math.isnan(scan.ranges[1])
    image = round_trip(
        "sensor_msgs/CompressedImage",
        {"format": "jpeg", "data": base64.b64encode(b"\xff\xd8\x01").decode()},
    )
    assert bytes(image.data) == b"\xff\xd8\x01"
    empty = round_trip("nav_msgs/Odometry", {})  # a missing fixed array is its zeros
    assert list(empty.pose.covariance) == [0.0] * 36


@pytest.mark.parametrize(
    ("type_name", "msg"),
    [
        ("geometry_msgs/Twist", {"linear": 5}),
        ("std_msgs/UInt8", {"data": 300}),
        ("sensor_msgs/CameraInfo", {"K": [1, 2]}),
        ("std_msgs/Float32MultiArray", {"data": ["x"]}),
        ("sensor_msgs/CompressedImage", {"data": "!!!"}),
    ],
)
def test_a_value_of_the_wrong_kind_is_an_encode_error(type_name, msg):
    with pytest.raises(ros1.Ros1EncodeError):
        ros1.encode(type_name, msg)
