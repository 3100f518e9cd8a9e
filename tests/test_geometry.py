"""The robot's planar geometry (``cloudnav_core.se2``): poses, frames and angles."""

from __future__ import annotations

import math

import numpy as np
import pytest

from cloudnav_core.se2 import (
    ahead,
    angle_between,
    compose,
    inverse,
    relative,
    transform,
    transform_each,
    wrap,
)

POSES = [(0.0, 0.0, 0.0), (1.5, -2.0, 0.7), (-3.0, 4.0, -2.9), (10.0, 0.5, math.pi)]


@pytest.mark.parametrize("angle", [0.0, math.pi, -math.pi, 3 * math.pi, -7.5, 1e3])
def test_wrapped_angles_lie_in_the_half_open_circle_and_point_the_same_way(angle):
    wrapped = wrap(angle)
    assert -math.pi <= wrapped < math.pi
    assert (math.cos(wrapped), math.sin(wrapped)) == pytest.approx(
        (math.cos(angle), math.sin(angle)), abs=1e-9
    )


def test_an_array_of_angles_wraps_as_each_angle_does():
    angles = np.array([0.0, math.pi, -7.5, 1e3])
    assert wrap(angles) == pytest.approx([wrap(float(a)) for a in angles])


def test_the_angle_between_two_headings_takes_the_short_way_round():
    assert angle_between(math.radians(179), math.radians(-179)) == pytest.approx(math.radians(2))
    assert angle_between(0.5, 0.5) == 0.0


@pytest.mark.parametrize("pose", POSES)
def test_a_pose_composed_with_its_inverse_is_the_identity(pose):
    assert compose(pose, inverse(pose)) == pytest.approx((0.0, 0.0, 0.0), abs=1e-12)
    assert compose(inverse(pose), pose) == pytest.approx((0.0, 0.0, 0.0), abs=1e-12)


@pytest.mark.parametrize("a", POSES)
@pytest.mark.parametrize("b", POSES)
def test_a_pose_seen_from_another_is_composing_with_the_inverse(a, b):
    seen = relative(a, b)
    expected = compose(inverse(a), b)
    assert seen[:2] == pytest.approx(expected[:2], abs=1e-12)
    assert angle_between(seen[2], expected[2]) == pytest.approx(0.0, abs=1e-12)
    back = compose(a, seen)
    assert back[:2] == pytest.approx(b[:2], abs=1e-12)


def test_composing_turns_the_child_offset_by_the_parent_heading():
    assert compose((1.0, 1.0, math.pi / 2), (2.0, 0.0, 0.0)) == pytest.approx(
        (1.0, 3.0, math.pi / 2)
    )


def test_ahead_follows_the_heading():
    assert ahead((1.0, 2.0, math.pi / 2), 0.5) == pytest.approx((1.0, 2.5))
    assert ahead((1.0, 2.0, 0.3), 0.0) == (1.0, 2.0)


def test_points_move_to_the_parent_frame_as_poses_do():
    pose = (1.5, -2.0, 0.7)
    points = np.array([[0.0, 0.0], [1.0, 0.0], [-0.5, 2.0]])
    moved = transform(pose, points)
    for (x, y), (px, py) in zip(points, moved, strict=True):
        assert (px, py) == pytest.approx(compose(pose, (x, y, 0.0))[:2])


def test_each_of_many_poses_moves_every_point():
    poses = np.array(POSES)
    x, y = np.array([0.0, 1.0, -0.5]), np.array([0.0, 0.0, 2.0])
    px, py = transform_each(poses, x, y)
    assert px.shape == py.shape == (len(POSES), 3)
    for row, pose in enumerate(POSES):
        expected = transform(pose, np.stack([x, y], 1))
        assert np.stack([px[row], py[row]], 1) == pytest.approx(expected)
