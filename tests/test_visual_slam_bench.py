"""``bench visual-slam`` on a tiny tour: one JSON object with the issue's keys, sane
values (the targets are the full bench's, not this test's), and its pieces: the tour
has loops, the alignment finds a known motion."""

from __future__ import annotations

import io
import itertools
import json
import math
from contextlib import redirect_stdout

import numpy as np
import pytest

from benchmarks import visual_slam
from benchmarks.visual_tracking import path_length
from cloudnav_core.se2 import aligning, transform

KEYS = {
    "seed",
    "tour_m",
    "frames",
    "ate_rmse_m",
    "rpe_per_m",
    "loop_closures",
    "false_loop_closures",
    "tracking_lost",
    "tracking_relocalised",
    "tracking_restarted",
    "frames_per_s",
    "cpu_per_robot",
    "grid_cell_agreement",
    "relocalise_success",
    "peer_ate_rmse_m",
    "peer_cpu_per_robot",
}


def test_the_default_tour_is_over_100_m_and_comes_back_to_where_it_began() -> None:
    poses = visual_slam.tour()
    assert path_length(poses) >= 100.0
    assert math.dist(poses[0][:2], poses[-1][:2]) < 1e-9  # twice round: loops to close
    steps = [math.dist(a[:2], b[:2]) for a, b in itertools.pairwise(poses)]
    assert max(steps) <= 0.1 + 1e-9


def test_aligning_finds_the_motion_between_two_copies_of_a_path() -> None:
    points = np.random.default_rng(0).normal(size=(30, 2))
    motion = (1.5, -0.5, 0.4)
    assert aligning(points, transform(motion, points)) == pytest.approx(motion)


@pytest.mark.slow
def test_a_tiny_tour_prints_one_json_object_with_the_keys() -> None:
    out = io.StringIO()
    options = {"seed": 0, "laps": 1, "metres": 2.0, "step": 0.1, "turn": 10.0}
    with redirect_stdout(out):
        visual_slam.run({**options, "wakeups": 2, "peer_scale": 0.5, "json": True})
    result = json.loads(out.getvalue())
    assert set(result) == KEYS
    assert result["frames"] == 21
    assert result["tour_m"] == 2.0
    assert result["tracking_lost"] == 0
    assert result["tracking_restarted"] == 0  # no odometry sent: nothing to restart from
    assert result["false_loop_closures"] == 0
    assert result["ate_rmse_m"] < 0.05
    assert result["peer_ate_rmse_m"] < 0.2
    assert 0.9 < result["grid_cell_agreement"] <= 1.0
    assert result["frames_per_s"] > 0
    assert result["cpu_per_robot"] > 0
    assert result["peer_cpu_per_robot"] > 0
    assert 0.0 <= result["relocalise_success"] <= 1.0


@pytest.mark.slow
def test_the_open3d_peer_follows_a_tour_with_a_right_angle_turn() -> None:
    # 15 m: Corridor A east, the slight turn to the atrium's door and a right angle. The
    # peer set up wrong (the last step as the next one's only guess) ran metres away here.
    poses = visual_slam.shortened(visual_slam.tour(1), 15.0)
    assert path_length(poses) > 14.0
    peer = visual_slam.run_peer(poses[0], visual_slam.robot_messages(poses, 0), [], 0.5)
    assert len(peer.poses) == len(poses)
    assert peer.failed == 0
    assert visual_slam.ate_rmse(peer.poses, poses) < 0.5
