"""Visual SLAM in its domain: tracking rendered frames with known motion, a loop closed on
a tour, tracking lost on a blank view then recovered by relocalisation, and mapping
started again from odometry where the map has nothing to relocalise on."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
import pytest

from benchmarks.visual_tracking import START, corridor_tour, rendered
from cloudnav_core.se2 import Pose, angle_between, compose, relative
from maps.domain.demo_building import demo_building
from maps.domain.keyframes import Depth, Image
from maps.domain.visual_slam import State, Tracked, VisualSlam, VisualSlamParams
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


def drive_with_odometry(
    mapper: VisualSlam, frames: list[tuple[Image, Depth]], odometry: Sequence[Pose | None]
) -> list[Tracked]:
    return [mapper.track(i, d, o) for (i, d), o in zip(frames, odometry, strict=True)]


def test_a_session_started_facing_a_plain_wall_maps_on_from_odometry_as_it_turns() -> None:
    start = demo_building().robot_starts[0]  # the entrance tag's plain wall at 0.45 m
    poses = [compose(start, (0.0, 0.0, math.radians(10.0 * k))) for k in range(37)]
    mapper = VisualSlam(default_vocabulary(), start)
    tracked = drive_with_odometry(mapper, rendered(poses, 1), list(poses))
    assert tracked[0].keyframe
    assert tracked[1].state is State.LOST  # the wall's one plane places nothing
    restarted = [i for i, t in enumerate(tracked) if t.state is State.RESTARTED]
    assert restarted[0] == VisualSlamParams().restart_after_lost
    assert all(t.state is State.TRACKING for t in tracked[restarted[0] + 1 : restarted[0] + 6])
    assert sum(t.state is State.LOST for t in tracked) < len(tracked) / 2
    assert len(mapper.keyframes) > 5
    for found, truth in zip(tracked, poses, strict=True):
        assert position_error(found, truth) < 0.1
        assert angle_between(found.pose[2], truth[2]) < math.radians(2.0)


COVERED = (np.full((480, 640), 128, np.uint8), np.full((480, 640), 0.6, np.float32))
"""What a covered camera sees: no texture to map from."""


def covered_turn(then: list[Pose] | None = None) -> tuple[list[tuple[Image, Depth]], list[Pose]]:
    """Frames and true poses: 1 m mapped east along Corridor A (11 frames), the camera
    covered while the robot turns 180 degrees (18), then 3 m driven west (30), views the
    map has none of, and ``then`` driven further (from the last pose)."""
    mapped = [compose(START, (2.0 + 0.1 * i, 0.0, 0.0)) for i in range(11)]
    turn = [compose(mapped[-1], (0.0, 0.0, math.radians(10.0 * k))) for k in range(1, 19)]
    back = [compose(turn[-1], (0.1 * i, 0.0, 0.0)) for i in range(1, 31)]
    further = [compose(back[-1], step) for step in then or []]
    frames = rendered(mapped, 1) + [COVERED] * len(turn) + rendered(back + further, 1)
    return frames, mapped + turn + back + further


def test_a_camera_covered_while_turning_away_maps_again_from_odometry_once_uncovered() -> None:
    frames, poses = covered_turn()
    mapper = VisualSlam(default_vocabulary(), poses[0])
    tracked = drive_with_odometry(mapper, frames, list(poses))
    mapped = sum(t.keyframe for t in tracked[:11])
    assert all(t.state is State.LOST for t in tracked[11:29])  # covered: too bare to map
    assert tracked[29].state is State.RESTARTED  # the first frame uncovered
    assert all(t.state is State.TRACKING for t in tracked[30:])
    assert len(mapper.keyframes) > mapped + 5
    restart = mapper.edges[mapped - 1]
    assert restart[:2] == (mapped - 1, mapped)  # tied to the last keyframe tracked
    assert restart[3] == VisualSlamParams().restart_sigmas
    assert position_error(tracked[-1], poses[-1]) < 0.05
    assert angle_between(tracked[-1].pose[2], poses[-1][2]) < math.radians(1.5)


@pytest.mark.slow  # about 120 frames
def test_a_loop_closure_pulls_a_restart_that_odometry_misplaced_into_place() -> None:
    turn = [(0.0, 0.0, math.radians(10.0 * k)) for k in range(1, 19)]
    east = [compose(turn[-1], (0.1 * i, 0.0, 0.0)) for i in range(1, 41)]
    frames, poses = covered_turn(then=turn + east)  # back over the first metre mapped
    slipped = compose(poses[10], (0.15, 0.2, math.radians(5.0)))  # wheels slipped, covered
    odometry = poses[:11] + [compose(slipped, relative(poses[10], p)) for p in poses[11:]]
    mapper = VisualSlam(default_vocabulary(), poses[0])
    tracked = drive_with_odometry(mapper, frames, odometry)
    restart = next(i for i, t in enumerate(tracked) if t.state is State.RESTARTED)
    closing = next(i for i, t in enumerate(tracked) if t.loop_closed)
    assert position_error(tracked[restart], poses[restart]) > 0.2
    assert position_error(tracked[closing - 1], poses[closing - 1]) > 0.1
    assert position_error(tracked[closing], poses[closing]) < 0.02
    assert mapper.loops[0][0] < sum(t.keyframe for t in tracked[:11])  # the first metre's
    restarted = mapper.keyframes[sum(t.keyframe for t in tracked[:restart])]
    assert math.dist(restarted.pose[:2], poses[restart][:2]) < 0.05  # pulled into place
    assert position_error(tracked[-1], poses[-1]) < 0.03


def test_without_odometry_a_lost_session_waits_for_relocalisation() -> None:
    frames, poses = covered_turn()
    mapper = VisualSlam(default_vocabulary(), poses[0])
    tracked = drive_with_odometry(mapper, frames, [None] * len(poses))
    assert all(t.state is State.LOST for t in tracked[11:])  # nothing says where it went
    assert len(mapper.keyframes) == sum(t.keyframe for t in tracked[:11])


def test_a_resumed_map_restarts_only_from_a_pose_it_placed_since() -> None:
    frames, poses = covered_turn()
    mapper = VisualSlam(default_vocabulary(), poses[0])
    drive_with_odometry(mapper, frames[:11], poses[:11])
    resumed = VisualSlam.resumed(
        default_vocabulary(), mapper.keyframes, mapper.edges, mapper.travelled_at, poses[10]
    )
    tracked = drive_with_odometry(resumed, frames[29:], poses[29:])  # carried elsewhere
    assert all(t.state is State.LOST for t in tracked)  # odometry is not counted from a guess
    assert len(resumed.keyframes) == len(mapper.keyframes)
