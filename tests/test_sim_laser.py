"""The simulated laser: ray casting on ground truth and extra obstacles."""

from __future__ import annotations

import math

import numpy as np
import pytest

from robots.agent.sim.laser import Laser, LaserSpec
from robots.agent.sim.world import Box, Cylinder, demo_world

# In Corridor A (walls at y = 22.0 and 24.4, west wall at x = 3.8), 1.2 m from each side.
POSE = (5.0, 23.2, 0.0)
QUIET = LaserSpec(noise_sigma=0.0)


def beam(spec: LaserSpec, angle: float) -> int:
    """Index of the beam pointing ``angle`` radians left of the robot's heading."""
    return round((angle - spec.angle_min) / spec.angle_increment) % spec.beams


def test_it_sees_the_walls_at_the_right_distance() -> None:
    ranges = Laser(demo_world(), QUIET).scan(POSE)
    assert ranges[beam(QUIET, math.pi / 2)] == pytest.approx(1.2, abs=1e-5)
    assert ranges[beam(QUIET, -math.pi / 2)] == pytest.approx(1.2, abs=1e-5)
    assert ranges[beam(QUIET, math.pi)] == pytest.approx(1.2, abs=1e-5)
    slant = beam(QUIET, math.radians(30))
    assert ranges[slant] == pytest.approx(1.2 / math.sin(math.radians(30)), abs=1e-4)


def test_it_reports_no_return_beyond_its_range() -> None:
    ranges = Laser(demo_world(), QUIET).scan(POSE)
    assert math.isinf(ranges[beam(QUIET, 0.0)])  # 12.8 m of corridor ahead, 8 m range


def test_it_sees_an_obstacle_that_is_on_no_map() -> None:
    world = demo_world().with_obstacles(Box(6.0, 23.0, 6.4, 23.4), Cylinder(5.0, 22.6, 0.2))
    ranges = Laser(world, QUIET).scan(POSE)
    assert ranges[beam(QUIET, 0.0)] == pytest.approx(1.0, abs=0.05)
    assert ranges[beam(QUIET, -math.pi / 2)] == pytest.approx(0.4, abs=0.05)


def test_its_mount_offset_shortens_ranges_ahead() -> None:
    spec = LaserSpec(noise_sigma=0.0, mount_x=0.1)
    ranges = Laser(demo_world(), spec).scan((5.0, 23.2, math.pi / 2))
    assert ranges[beam(spec, 0.0)] == pytest.approx(1.1, abs=1e-5)


def test_its_noise_is_small_and_seeded() -> None:
    first = Laser(demo_world(), seed=1).scan(POSE)
    again = Laser(demo_world(), seed=1).scan(POSE)
    exact = Laser(demo_world(), QUIET).scan(POSE)
    np.testing.assert_array_equal(first, again)
    finite = np.isfinite(exact) & np.isfinite(first)
    assert 0 < np.abs(first[finite] - exact[finite]).max() < 0.05


def test_its_message_writes_no_return_as_null() -> None:
    laser = Laser(demo_world(), QUIET)
    message = laser.message(laser.scan(POSE), seconds=12.25)
    assert message["header"] == {
        "stamp": {"sec": 12, "nanosec": 250_000_000},
        "frame_id": "base_scan",
    }
    assert len(message["ranges"]) == 360
    assert message["ranges"][beam(QUIET, 0.0)] is None
    assert message["ranges"][beam(QUIET, math.pi / 2)] == pytest.approx(1.2, abs=1e-5)
    assert message["angle_min"] == -math.pi
    assert message["angle_max"] == pytest.approx(math.pi - message["angle_increment"])
    assert (message["range_min"], message["range_max"]) == (0.12, 8.0)
