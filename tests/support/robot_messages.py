"""A robot's pose and scan messages numbered ``i``, as the recording tests publish them."""

from __future__ import annotations


def pose(i: int) -> dict:
    return {
        "header": {"stamp": {"sec": 100 + i, "nanosec": i}, "frame_id": "boccioni_1/Hall"},
        "pose": {"position": {"x": i * 0.5, "y": -i}, "orientation": {"z": 0.0, "w": 1.0}},
    }


def scan(i: int) -> dict:
    return {
        "header": {"stamp": {"sec": 100 + i, "nanosec": 0}, "frame_id": "laser"},
        "angle_min": -1.0,
        "angle_max": 1.0,
        "angle_increment": 1.0,
        "range_min": 0.1,
        "range_max": 8.0,
        "ranges": [float(i), 2.0, 3.0],
    }
