"""The simulated differential-drive body: motion, limits, walls, watchdog, odometry."""

from __future__ import annotations

import math

import pytest

from cloudnav_core.params import BodyLimits
from robots.agent.sim.body import EXACT_ODOMETRY, DiffDriveBody, OdometryNoise
from robots.agent.sim.world import demo_world

# Corridor A runs east-west between walls at y = 22.0 and y = 24.4, from x = 3.8 to 17.8.
CORRIDOR = (5.0, 23.2)


def make_body(yaw: float = 0.0, **kwargs: object) -> DiffDriveBody:
    kwargs.setdefault("noise", EXACT_ODOMETRY)
    return DiffDriveBody(demo_world(), (*CORRIDOR, yaw), **kwargs)  # type: ignore[arg-type]


def drive(body: DiffDriveBody, linear: float, angular: float, seconds: float) -> None:
    """Keep commanding, as a teleop client does at 10 Hz."""
    for _ in range(round(seconds / 0.1)):
        body.command(linear, angular)
        body.advance(0.1)


def test_it_drives_a_straight_line_at_the_commanded_speed() -> None:
    body = make_body()
    drive(body, 0.4, 0.0, 3.0)
    x, y, yaw = body.pose
    # 0.4 s of ramping up at 1 m/s^2 loses 0.08 m against constant speed.
    assert x - CORRIDOR[0] == pytest.approx(0.4 * 3.0 - 0.08, abs=0.01)
    assert y == pytest.approx(CORRIDOR[1])
    assert yaw == pytest.approx(0.0)
    assert body.velocity == pytest.approx((0.4, 0.0))


def test_it_turns_on_the_spot() -> None:
    body = make_body()
    drive(body, 0.0, 1.0, 2.0)
    x, y, yaw = body.pose
    assert (x, y) == pytest.approx(CORRIDOR)
    # 0.25 s of ramping up at 4 rad/s^2 loses 0.125 rad against constant speed (less
    # half a step, since each step moves at the speed reached at its start).
    assert yaw == pytest.approx(2.0 - 0.125, abs=0.011)


def test_it_follows_an_arc_when_driving_and_turning() -> None:
    instant = BodyLimits(linear_accel=1e6, angular_accel=1e6)
    body = make_body(limits=instant)
    drive(body, 0.3, 0.3, 2.0)
    x, y, _ = body.pose
    radius = 0.3 / 0.3
    assert math.hypot(x - CORRIDOR[0], y - (CORRIDOR[1] + radius)) == pytest.approx(
        radius, abs=1e-3
    )


def test_it_clamps_commands_to_its_limits() -> None:
    body = make_body(limits=BodyLimits(max_linear=0.5, max_angular=1.5))
    drive(body, 3.0, 0.0, 2.0)
    assert body.velocity[0] == pytest.approx(0.5)
    drive(body, 0.0, -9.0, 1.0)
    assert body.velocity[1] == pytest.approx(-1.5)


def test_it_stops_at_a_wall_instead_of_passing_through() -> None:
    body = make_body(yaw=math.pi / 2)  # facing the north wall, 1.2 m away
    drive(body, 0.5, 0.0, 5.0)
    assert body.bumped
    assert body.velocity[0] == 0.0
    gap = 24.4 - body.pose[1]
    assert body.limits.radius <= gap < body.limits.radius + 0.01


def test_it_can_back_away_from_a_wall_it_touches() -> None:
    body = DiffDriveBody(demo_world(), (5.0, 24.4 - 0.1, math.pi / 2), noise=EXACT_ODOMETRY)
    drive(body, 0.3, 0.0, 1.0)
    assert body.pose[1] == pytest.approx(24.3)  # pushing on: nowhere to go
    drive(body, -0.3, 0.0, 1.0)
    assert body.pose[1] < 24.1
    assert not body.bumped


def test_it_stops_by_itself_half_a_second_after_the_last_command() -> None:
    body = make_body()
    drive(body, 0.5, 0.0, 1.0)
    body.command(0.5, 0.0)
    body.advance(0.46)
    assert body.velocity[0] == pytest.approx(0.5)
    body.advance(0.06)  # past 0.5 s: the watchdog zeroes the wanted velocity
    assert body.velocity[0] < 0.5
    body.advance(0.5)  # braking at 1 m/s^2 takes 0.5 s
    assert body.velocity == (0.0, 0.0)
    resting = body.pose
    body.advance(1.0)
    assert body.pose == resting


def test_its_odometry_drifts_but_stays_close_to_the_truth() -> None:
    body = make_body(noise=OdometryNoise(), seed=7)
    drive(body, 0.4, 0.1, 10.0)
    truth = _relative_to_start(body.pose, (*CORRIDOR, 0.0))
    odom = body.odom_pose
    # About 4 m driven and 1 rad turned: sigmas near 0.04 m and 0.035 rad (this seed is
    # a 3-sigma heading draw; the bounds allow 4).
    assert 0 < math.dist(truth[:2], odom[:2]) < 0.2
    assert 0 < abs(truth[2] - odom[2]) < 0.15


def test_its_odometry_is_exact_without_noise_and_starts_at_zero() -> None:
    body = make_body()
    assert body.odom_pose == (0.0, 0.0, 0.0)
    drive(body, 0.4, 0.2, 4.0)
    truth = _relative_to_start(body.pose, (*CORRIDOR, 0.0))
    assert body.odom_pose == pytest.approx(truth, abs=1e-9)


def test_the_same_seed_gives_the_same_run() -> None:
    runs = []
    for _ in range(2):
        body = make_body(noise=OdometryNoise(), seed=3)
        drive(body, 0.3, 0.2, 3.0)
        runs.append(body.odom_pose)
    assert runs[0] == runs[1]


def test_it_refuses_to_integrate_slower_than_20_hz() -> None:
    with pytest.raises(ValueError, match="20 Hz"):
        make_body(rate_hz=10)


def test_its_odometry_message_is_rosbridge_json() -> None:
    body = make_body()
    drive(body, 0.2, 0.0, 1.0)
    message = body.odometry_message()
    assert message["header"]["frame_id"] == "odom"
    assert message["header"]["stamp"] == {"sec": 1, "nanosec": 0}
    assert message["child_frame_id"] == "base_footprint"
    assert message["pose"]["pose"]["position"]["x"] == pytest.approx(body.odom_pose[0])
    assert message["pose"]["pose"]["orientation"]["w"] == pytest.approx(1.0)
    assert len(message["pose"]["covariance"]) == 36
    assert message["twist"]["twist"]["linear"]["x"] == pytest.approx(0.2)
    stamped = body.odometry_message(seconds=1_700_000_000.5)
    assert stamped["header"]["stamp"] == {"sec": 1_700_000_000, "nanosec": 500_000_000}


def _relative_to_start(
    pose: tuple[float, float, float], start: tuple[float, float, float]
) -> tuple[float, float, float]:
    """``pose`` in the frame of ``start`` (where odometry began)."""
    dx, dy = pose[0] - start[0], pose[1] - start[1]
    c, s = math.cos(start[2]), math.sin(start[2])
    return c * dx + s * dy, -s * dx + c * dy, pose[2] - start[2]
