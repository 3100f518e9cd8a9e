"""The timed elastic band: the band's constraints on straight, turning and blocked paths,
its resizing and exact Jacobian, and obstacles tracked at constant velocity."""

from __future__ import annotations

import math

import numpy as np
import pytest

from cloudnav_core.params import RobotConfig
from cloudnav_core.se2 import compose, inverse, transform
from robots.agent.teb import (
    Band,
    TimedElasticBand,
    _problem,
    band_from_path,
    resized,
)
from robots.agent.tracking import ObstacleTracker, SeenObstacles

CONFIG = RobotConfig(local_planner="teb")
BODY = CONFIG.body
NONE = np.zeros((0, 2))


def corridor_walls(half_width: float = 1.2) -> np.ndarray:
    xs = np.arange(-1.0, 4.0, 0.05)
    return np.concatenate(
        [np.column_stack([xs, np.full_like(xs, s * half_width)]) for s in (1.0, -1.0)]
    )


def plan(path: list[tuple[float, float]], points: np.ndarray, cycles: int = 5, **kw):
    """The planner's choice after ``cycles`` control periods standing at the origin."""
    planner = TimedElasticBand(CONFIG)
    line = np.array(path, np.float64)
    yaw = math.atan2(line[-1, 1] - line[-2, 1], line[-1, 0] - line[-2, 0])
    for cycle in range(cycles):
        choice = planner.choose(line, yaw, False, (0.3, 0.0), points, (0, 0, 0), 0.1 * cycle, **kw)
    return choice


def nonholonomic_error(band: Band) -> float:
    delta = np.diff(band.poses[:, :2], axis=0)
    c, s = np.cos(band.poses[:, 2]), np.sin(band.poses[:, 2])
    error = (c[:-1] + c[1:]) * delta[:, 1] - (s[:-1] + s[1:]) * delta[:, 0]
    return float(np.abs(error).max())


def assert_within_limits(band: Band) -> None:
    linear, angular = band.velocities()
    assert np.abs(linear).max() <= BODY.max_linear * 1.05
    assert np.abs(angular).max() <= BODY.max_angular * 1.05
    assert (linear >= -1e-3).all()  # forwards only
    assert nonholonomic_error(band) < 0.01
    assert (band.dts > 0).all()


def test_on_a_straight_path_the_band_runs_straight_at_top_speed() -> None:
    choice = plan([(0.0, 0.0), (2.5, 0.0)], corridor_walls())
    band = choice.band
    assert not choice.blocked
    assert band is not None
    assert np.abs(band.poses[:, 1]).max() < 0.02
    assert_within_limits(band)
    assert band.times[-1] == pytest.approx(2.5 / BODY.max_linear, rel=0.15)
    assert choice.command[0] == pytest.approx(min(0.3 + BODY.linear_accel * 0.1, 0.5))
    assert abs(choice.command[1]) < 0.05


def test_on_a_turning_path_the_band_turns_within_the_limits_and_kinematics() -> None:
    choice = plan([(0.0, 0.0), (1.2, 0.0), (1.2, 1.5)], NONE)
    band = choice.band
    assert not choice.blocked
    assert band is not None
    assert_within_limits(band)
    assert band.poses[-1, 2] == pytest.approx(math.pi / 2)
    turning = np.abs(band.velocities()[1])
    assert turning.max() > 0.5  # it does turn on the way, not only at the end
    # It cuts the corner a little, as a band that trades via-points against time does.
    off = np.minimum(np.abs(band.poses[:, 1]), np.abs(band.poses[:, 0] - 1.2))
    assert off.max() < 0.35


def test_a_band_swerves_round_something_on_the_path_and_keeps_clear_of_it() -> None:
    bin_ = np.array([[1.2, y] for y in np.arange(-0.15, 0.16, 0.05)])
    choice = plan([(0.0, 0.0), (2.5, 0.0)], np.concatenate([corridor_walls(), bin_]))
    band = choice.band
    assert not choice.blocked
    assert band is not None
    gaps = np.hypot(*(band.poses[:, None, :2] - bin_[None]).transpose(2, 0, 1)).min()
    assert gaps >= BODY.radius + 0.02
    assert_within_limits(band)


def test_a_blocked_path_stops_the_robot_short_of_what_blocks_it() -> None:
    planner = TimedElasticBand(CONFIG)
    across = np.array([[1.0, y] for y in np.arange(-1.2, 1.21, 0.05)])
    seen = np.concatenate([corridor_walls(), across])  # a wall right across, 1 m ahead
    pose, velocity, blocked = (0.0, 0.0, 0.0), (0.0, 0.0), False
    for cycle in range(80):
        path = transform(inverse(pose), np.array([pose[:2], (2.5, 0.0)]))
        local = transform(inverse(pose), seen)
        choice = planner.choose(path, -pose[2], False, velocity, local, pose, 0.1 * cycle)
        blocked |= choice.blocked
        velocity = choice.command
        pose = compose(pose, (velocity[0] * 0.1, 0.0, velocity[1] * 0.1))
        assert pose[0] < 1.0 - BODY.radius
    assert blocked
    assert velocity == (0.0, 0.0)


def test_the_band_grows_and_shrinks_to_keep_its_intervals_near_dt_ref() -> None:
    teb = CONFIG.teb
    sparse = Band(np.array([[0, 0, 0], [1.0, 0, 0], [2.0, 0, 0]], float), np.array([2.0, 2.0]))
    grown = resized(sparse, teb)
    assert len(grown.poses) > 3
    assert grown.dts.max() <= teb.dt_ref + teb.dt_hysteresis
    assert grown.times[-1] == pytest.approx(4.0)
    dense = Band(np.linspace([0, 0, 0], [0.3, 0, 0], 11), np.full(10, 0.03))
    shrunk = resized(dense, teb)
    assert len(shrunk.poses) < 11
    assert shrunk.times[-1] == pytest.approx(0.3)


def test_its_jacobian_is_exact() -> None:
    band = band_from_path(np.array([[0.0, 0.0], [1.0, 0.2], [2.0, 1.0]]), 0.8, CONFIG)
    band.poses[1:-1] += np.random.default_rng(1).normal(0, 0.05, band.poses[1:-1].shape)
    seen = SeenObstacles(np.array([[1.0, 0.5], [1.5, 0.2]]), np.array([[0.0, -0.3], [0, 0]]))
    problem = _problem(band, band.poses[:, :2], (0.2, 0.1), seen, True, CONFIG)
    x = problem.pack(band)
    numeric = np.column_stack(
        [
            (problem.residuals(x + e) - problem.residuals(x - e)) / 2e-6
            for e in np.eye(len(x)) * 1e-6
        ]
    )
    np.testing.assert_allclose(problem.jacobian(x), numeric, atol=1e-4)


def test_a_moving_cluster_gets_its_velocity_and_walls_stand_still() -> None:
    tracker = ObstacleTracker()
    wall = np.column_stack([np.arange(-1.0, 3.0, 0.05), np.full(80, 1.2)])
    for tick in range(6):
        person = np.array([[2.0, -0.5 + 0.1 * tick + dy] for dy in (-0.1, 0.0, 0.1)])
        seen = tracker.update(np.concatenate([wall, person]), (0.0, 0.0, 0.0), 0.1 * tick)
    velocities = seen.velocities
    assert np.abs(velocities[: len(wall)]).max() == 0.0
    np.testing.assert_allclose(velocities[len(wall) :], [[0.0, 1.0]] * 3, atol=0.05)
    np.testing.assert_allclose(seen.at(1.0)[-1], person[-1] + (0.0, 1.0), atol=0.05)


def test_velocities_are_tracked_in_the_odometry_frame_while_the_robot_turns() -> None:
    tracker = ObstacleTracker()
    for tick in range(6):
        yaw = 0.2 * tick  # the robot turns on the spot; the thing stands still
        world = np.array([[2.0, 0.0], [2.0, 0.1]])
        c, s = math.cos(yaw), math.sin(yaw)
        local = np.column_stack(
            [c * world[:, 0] + s * world[:, 1], -s * world[:, 0] + c * world[:, 1]]
        )
        seen = tracker.update(local, (0.0, 0.0, yaw), 0.1 * tick)
    assert np.abs(seen.velocities).max() == 0.0
