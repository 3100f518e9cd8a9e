"""Near-duplicate keyframes: the one rule the keyframe store applies as it saves and the
visual SLAM bench applies to the relocalisation map publishing would store."""

from __future__ import annotations

import math

import numpy as np

from maps.domain.keyframes import DUPLICATE_DISTANCE, DUPLICATE_YAW, Keyframe, thinned


def keyframe_at(pose: tuple[float, float, float]) -> Keyframe:
    empty = np.zeros((0, 3), np.float32)
    return Keyframe(pose, np.zeros((0, 32), np.uint8), empty, np.zeros(8, np.float32))


def test_a_keyframe_near_and_facing_like_one_kept_is_dropped() -> None:
    poses = [(1.0, 2.0, 0.0), (1.0 + DUPLICATE_DISTANCE, 2.0, DUPLICATE_YAW), (1.05, 2.0, 0.1)]
    assert [k.pose for k in thinned([keyframe_at(p) for p in poses])] == [poses[0]]


def test_keyframes_farther_off_or_facing_elsewhere_are_kept_in_order() -> None:
    poses = [
        (1.0, 2.0, math.pi - 0.05),
        (1.0, 2.0 + DUPLICATE_DISTANCE + 0.01, math.pi),
        (1.0, 2.0, -math.pi + 0.05),  # across the wrap: a duplicate of the first
        (1.0, 2.0, math.pi - 0.05 - DUPLICATE_YAW - 0.01),
    ]
    kept = thinned([keyframe_at(p) for p in poses])
    assert [k.pose for k in kept] == [poses[0], poses[1], poses[3]]


def test_only_kept_keyframes_make_later_ones_duplicates() -> None:
    # The second is dropped as the first's duplicate, so it cannot drop the third.
    step = 0.8 * DUPLICATE_DISTANCE
    poses = [(0.0, 0.0, 0.0), (step, 0.0, 0.0), (2 * step, 0.0, 0.0)]
    assert [k.pose for k in thinned([keyframe_at(p) for p in poses])] == [poses[0], poses[2]]
