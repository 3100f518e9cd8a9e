"""A robot with an RGB-D camera and no laser: its planar scan made from depth (as
``depthimage_to_laserscan`` makes it), and what it remembers of returns out of view."""

from __future__ import annotations

import math

import numpy as np
import pytest

from cloudnav_core.camera import CameraModel
from cloudnav_core.params import RobotConfig
from robots.agent.depth_scan import DepthScanSpec, ObstacleMemory, depth_to_scan
from robots.agent.sim.hardware import SimHardware
from robots.agent.sim.world import demo_world

MODEL = CameraModel()
SPEC = DepthScanSpec()


def test_a_wall_square_to_the_camera_gives_its_distance_over_the_cosine_of_each_bearing() -> None:
    depth = np.full((MODEL.height, MODEL.width), 2.0, np.float32)
    ranges = depth_to_scan(depth, MODEL, SPEC)
    angles = SPEC.angles(MODEL)
    assert ranges.shape == angles.shape == (SPEC.beams,)
    # Each beam keeps the nearest column binned to it: within half an increment.
    increment = angles[1] - angles[0]
    assert np.all(ranges <= 2.0 / np.cos(angles) + 1e-6)
    assert np.all(ranges >= 2.0 / np.cos(np.abs(angles) - increment / 2) - 1e-6)


def test_the_scan_spans_the_cameras_field_of_view_left_positive() -> None:
    low, high = SPEC.field_of_view(MODEL)
    assert low == pytest.approx(-math.atan(319.5 / 525.0))  # column 639
    assert high == pytest.approx(math.atan(319.5 / 525.0))
    depth = np.full((MODEL.height, MODEL.width), np.inf, np.float32)
    depth[:, :40] = 1.5  # something on the image's left: the scan's last beams
    ranges = depth_to_scan(depth, MODEL, SPEC)
    assert np.isfinite(ranges[-5:]).all()
    assert np.isinf(ranges[:-20]).all()


def test_readings_the_camera_cannot_take_are_no_return() -> None:
    depth = np.zeros((MODEL.height, MODEL.width), np.float32)  # 0: nothing read
    depth[:, 100:200] = np.nan
    depth[:, 200:300] = 0.1  # nearer than range_min
    depth[:, 300:400] = 50.0  # farther than range_max
    assert np.isinf(depth_to_scan(depth, MODEL, SPEC)).all()


def test_the_nearest_row_of_the_scan_band_wins_and_rows_outside_it_are_not_read() -> None:
    depth = np.full((MODEL.height, MODEL.width), 3.0, np.float32)
    rows = SPEC.rows(MODEL)
    depth[rows[-1], :] = 1.0  # a low edge inside the band
    depth[: rows[0], :] = 0.5  # the ceiling of a low room, above the band
    ranges = depth_to_scan(depth, MODEL, SPEC)
    assert ranges.max() < 1.0 / math.cos(SPEC.field_of_view(MODEL)[0]) + 1e-6


def test_depth_of_another_width_is_refused() -> None:
    with pytest.raises(ValueError, match="640 columns"):
        depth_to_scan(np.ones((480, 320), np.float32), MODEL, SPEC)


def test_the_simulated_camera_only_robot_scans_what_a_laser_at_its_camera_would_see() -> None:
    world = demo_world()
    start = (5.0, 23.2, 0.3)  # Corridor A, looking along it and at its north wall
    robot = SimHardware(world, start, sensors="rgbd")
    ranges = robot.scan().astype(np.float64)
    eye = (start[0] + MODEL.mount_x * math.cos(start[2]), start[1] + MODEL.mount_x * math.sin(0.3))
    truth = world.cast(*eye, start[2] + robot.scan_angles, 30.0).distance
    near = np.isfinite(ranges)
    assert near.sum() > 40  # the north wall and the corridor's far end out of range
    assert near[truth < SPEC.range_max - 0.2].all()
    assert not near[truth > SPEC.range_max + 0.2].any()
    # Columns binned to a beam differ in bearing by up to half an increment.
    assert np.abs(ranges[near] - truth[near]).max() < 0.1
    assert np.median(np.abs(ranges[near] - truth[near])) < 0.02
    assert robot.scan_mount == (MODEL.mount_x, 0.0, 0.0)


def test_the_camera_only_robot_publishes_its_scan_as_a_laser_scan_of_its_field_of_view() -> None:
    robot = SimHardware(demo_world(), (5.0, 23.2, 0.0), sensors="rgbd")
    message = robot.scan_message(robot.scan(), 12.5)
    assert message["header"]["frame_id"] == "camera_depth_frame"
    assert len(message["ranges"]) == SPEC.beams
    assert message["angle_min"] == pytest.approx(SPEC.field_of_view(MODEL)[0])
    count = round((message["angle_max"] - message["angle_min"]) / message["angle_increment"]) + 1
    assert count == SPEC.beams
    assert (message["range_min"], message["range_max"]) == (SPEC.range_min, SPEC.range_max)


def test_an_unknown_sensor_set_is_refused() -> None:
    with pytest.raises(ValueError, match="sensors"):
        RobotConfig(sensors="sonar")  # type: ignore[arg-type]


# --- what the camera saw ---------------------------------------------------------------

ANGLES = np.linspace(-0.5, 0.5, 11)


def scan_with(hit: int | None, distance: float = 1.0) -> np.ndarray:
    ranges = np.full(len(ANGLES), np.inf)
    if hit is not None:
        ranges[hit] = distance
    return ranges


def test_a_return_that_left_the_field_of_view_is_remembered_where_it_now_is() -> None:
    memory = ObstacleMemory(keep=4.0)
    memory.update(scan_with(5), ANGLES, (0.0, 0.0, 0.0), 0.0)  # 1 m straight ahead
    turned = (0.0, 0.0, math.pi / 2)  # a quarter turn left: the point is now on the right
    points = memory.update(scan_with(None), ANGLES, turned, 1.0)
    assert points.shape == (1, 2)
    assert points[0] == pytest.approx([0.0, -1.0], abs=1e-9)


def test_a_remembered_return_is_forgotten_after_keep_seconds() -> None:
    memory = ObstacleMemory(keep=4.0)
    memory.update(scan_with(5), ANGLES, (0.0, 0.0, 0.0), 0.0)
    turned = (0.0, 0.0, math.pi / 2)
    assert len(memory.update(scan_with(None), ANGLES, turned, 3.9)) == 1
    assert len(memory.update(scan_with(None), ANGLES, turned, 4.1)) == 0


def test_a_remembered_return_the_camera_now_sees_through_is_cleared() -> None:
    memory = ObstacleMemory(keep=4.0)
    memory.update(scan_with(5, 1.0), ANGLES, (0.0, 0.0, 0.0), 0.0)  # a person 1 m ahead
    points = memory.update(scan_with(5, 3.0), ANGLES, (0.0, 0.0, 0.0), 0.2)  # walked away
    assert points.tolist() == [[3.0, 0.0]]


def test_a_return_behind_what_the_camera_sees_now_stays() -> None:
    memory = ObstacleMemory(keep=4.0)
    memory.update(scan_with(5, 3.0), ANGLES, (0.0, 0.0, 0.0), 0.0)
    points = memory.update(scan_with(5, 1.0), ANGLES, (0.0, 0.0, 0.0), 0.2)  # hidden now
    assert sorted(points.tolist()) == [[1.0, 0.0], [3.0, 0.0]]


def test_with_nothing_kept_the_view_is_the_latest_scan_from_the_sensors_mount() -> None:
    memory = ObstacleMemory(mount=(0.05, 0.0, 0.0), keep=0.0)
    memory.update(scan_with(5), ANGLES, (0.0, 0.0, 0.0), 0.0)
    points = memory.update(scan_with(0, 2.0), ANGLES, (0.0, 0.0, math.pi / 2), 0.1)
    assert points == pytest.approx(np.array([[0.05 + 2.0 * math.cos(-0.5), 2.0 * math.sin(-0.5)]]))


# --- where a camera-only robot may move ------------------------------------------------

WIDE = np.linspace(-0.5, 0.5, 101)  # the camera's field of view, about 57 degrees


def scan_of_person(x: float, y: float, radius: float = 0.25) -> np.ndarray:
    """Ranges along ``WIDE`` from the origin to a person (a disc) at ``(x, y)``."""
    along = x * np.cos(WIDE) + y * np.sin(WIDE)
    miss = (x * x + y * y) - along**2
    inside = radius**2 - miss
    return np.where((inside >= 0) & (along > 0), along - np.sqrt(np.clip(inside, 0, None)), np.inf)


def person_walks_out_of_view(memory: ObstacleMemory) -> float:
    """A person 1.6 m ahead walks at 0.86 m/s towards the robot's left side and leaves
    the camera's view; returns the time of the last scan."""
    seconds, x, y = 0.0, 1.6, -0.3
    while y < 0.9:
        memory.update(scan_of_person(x, y), WIDE, (0.0, 0.0, 0.0), seconds)
        seconds, x, y = seconds + 0.1, x - 0.05, y + 0.07
    return seconds - 0.1


def test_floor_a_person_seen_walking_may_have_reached_is_off_limits_unless_seen_free() -> None:
    memory = ObstacleMemory(keep=4.0, range_max=6.0, range_min=0.2)
    now = person_walks_out_of_view(memory)
    memory.update(scan_with_nothing(), WIDE, (0.0, 0.0, 0.0), now + 0.5)
    may_enter = memory.may_enter(
        np.array([[0.5, 0.6], [0.2, 0.9], [1.0, 0.0], [1.5, -1.0], [-3.0, -3.0]]),
        (0.0, 0.0, 0.0),
    )
    # On the person's way out of view, beside the robot (never seen): off limits. Straight
    # ahead (seen free just now), and off their way (out of view, but they walked the
    # other way), allowed.
    assert may_enter.tolist() == [False, False, True, True, True]


def scan_with_nothing() -> np.ndarray:
    return np.full(len(WIDE), np.inf)


def test_with_nobody_seen_moving_a_camera_only_robot_may_move_anywhere() -> None:
    memory = ObstacleMemory(keep=4.0, range_max=6.0, range_min=0.2)
    for step in range(10):  # a pillar that stands
        memory.update(scan_of_person(1.5, 0.0), WIDE, (0.0, 0.0, 0.0), step * 0.1)
    beside = np.array([[0.0, 0.3], [0.0, -0.3], [-0.3, 0.0]])
    assert memory.may_enter(beside, (0.0, 0.0, 0.0)).all()


def test_a_person_seen_again_no_longer_holds_the_floor_they_left() -> None:
    memory = ObstacleMemory(keep=4.0, range_max=6.0, range_min=0.2)
    now = person_walks_out_of_view(memory)
    for step in range(1, 4):  # back into view, walking the other way
        memory.update(
            scan_of_person(1.5, 0.7 - 0.08 * step), WIDE, (0.0, 0.0, 0.0), now + step / 10
        )
    assert memory.may_enter(np.array([[0.3, 0.5]]), (0.0, 0.0, 0.0)).all()


def test_a_robot_that_sees_all_round_has_no_entry_check() -> None:
    memory = ObstacleMemory(keep=0.0)
    assert memory.entry_check((0.0, 0.0, 0.0)) is None
