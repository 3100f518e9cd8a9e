"""Visual SLAM in its domain: tracking rendered frames with known motion, a loop closed on
a tour, and tracking lost on a blank view then recovered by relocalisation."""

from __future__ import annotations

import math

import numpy as np
import pytest

from benchmarks.visual_tracking import START, corridor_tour, rendered
from cloudnav_core.se2 import Pose, angle_between, compose, relative
from maps.domain.visual_slam import State, Tracked, VisualSlam
from maps.domain.vocabulary import default_vocabulary
from maps.exceptions import KeyframeError
from robots.agent.sim.camera import Camera
from robots.agent.sim.world import demo_world


def slam() -> VisualSlam:
    return VisualSlam(default_vocabulary(), START)


def drive(mapper: VisualSlam, poses: list[Pose], seed: int = 1) -> list[Tracked]:
    return [mapper.track(image, depth) for image, depth in rendered(poses, seed)]


def position_error(tracked: Tracked, truth: Pose) -> float:
    return math.dist(tracked.pose[:2], truth[:2])


def test_it_tracks_rendered_frames_with_known_motion_within_a_few_millimetres_a_step() -> None:
    ahead = [compose(START, (0.08 * i, 0.0, 0.0)) for i in range(16)]
    turning = [compose(ahead[-1], (0.0, 0.0, math.radians(6.0 * k))) for k in range(1, 16)]
    poses = ahead + turning
    mapper = slam()
    tracked = drive(mapper, poses)
    assert all(t.state is State.TRACKING for t in tracked)
    for before, after, truth_before, truth_after in zip(
        tracked, tracked[1:], poses, poses[1:], strict=False
    ):
        step = relative(before.pose, after.pose)
        truth = relative(truth_before, truth_after)
        assert math.dist(step[:2], truth[:2]) < 0.02
        assert angle_between(step[2], truth[2]) < math.radians(1.0)
    assert position_error(tracked[-1], poses[-1]) < 0.05
    assert angle_between(tracked[-1].pose[2], poses[-1][2]) < math.radians(2.0)
    assert len(mapper.keyframes) >= 5  # moved 1.2 m and turned 90 degrees


def test_a_depth_image_that_does_not_match_the_image_is_refused() -> None:
    ((image, depth),) = rendered([START], 1)
    with pytest.raises(KeyframeError, match="must match"):
        slam().track(image, depth[::2, ::2])


@pytest.mark.slow  # about 160 frames
def test_a_loop_closed_on_a_tour_back_to_the_start_removes_the_accumulated_drift() -> None:
    poses = corridor_tour(length=6.0, step=0.1, turn=math.radians(10.0))
    mapper = slam()
    tracked = drive(mapper, poses)
    closing = next(i for i, t in enumerate(tracked) if t.loop_closed)
    drift = position_error(tracked[closing - 1], poses[closing - 1])
    after = position_error(tracked[closing], poses[closing])
    assert mapper.loops[0][0] < 5  # closed on the first keyframes
    assert after < 0.5 * drift
    assert after < 0.03
    assert position_error(tracked[-1], poses[-1]) < 0.03
    assert all(t.state is not State.LOST for t in tracked)


def test_tracking_lost_on_a_blank_wall_is_recovered_by_relocalisation_after_a_jump() -> None:
    poses = [compose(START, (0.08 * i, 0.0, 0.0)) for i in range(12)]
    mapper = slam()
    drive(mapper, poses)
    blank = mapper.track(np.full((480, 640), 128, np.uint8), np.full((480, 640), 0.6, np.float32))
    assert blank.state is State.LOST
    assert "texture" in blank.reason
    kidnapped = (START[0] + 0.3, START[1] + 0.15, math.radians(8.0))  # back, near the start
    image, depth = Camera(demo_world(seed=1), seed=5).capture(kidnapped)
    assert depth is not None
    found = mapper.track(image, depth)
    assert found.state is State.RELOCALISED
    assert position_error(found, kidnapped) < 0.05
    assert angle_between(found.pose[2], kidnapped[2]) < math.radians(1.5)
