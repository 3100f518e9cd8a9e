"""2D SLAM on a simulated tour against the ground truth: a room no sub-map covers,
mapped from a teleoperated tour, agrees with the truth; bad readings mark nothing; a
mapper's state resumes in another process."""

from __future__ import annotations

import math

import numpy as np
import pytest

from benchmarks.mapping import compare_with_truth, drive_tour
from maps.domain.demo_building import demo_building
from maps.domain.slam.mapper import Mapper
from maps.domain.slam.params import SlamParams
from maps.domain.slam.scans import Scan
from maps.exceptions import OutsideExtent
from robots.agent.sim.changes import ChangeConfig, changed_demo_world, changed_grid, plan_changes


@pytest.fixture(scope="module")
def tour():
    changes = plan_changes(0, ChangeConfig(rooms=1))
    return changes, drive_tour(0, changes.rooms[0], changed_demo_world(changes))


def mapped(scans, mapper: Mapper) -> Mapper:
    for scan in scans:
        mapper.add(scan.odom, Scan.from_message(scan.message, mapper.params.usable_range))
    return mapper


def test_a_toured_room_is_mapped_as_the_truth_has_it(tour) -> None:
    changes, scans = tour
    mapper = mapped(scans, Mapper(SlamParams(), start=scans[0].truth))
    building = demo_building()
    grid, origin = mapper.grid()
    truth = changed_grid(changes, building)
    agreement, rms = compare_with_truth(
        grid, origin, truth, building.world_origin, changes.rooms[0].interior
    )
    assert agreement >= 0.95
    assert rms <= 1.0
    assert mapper.stats.loop_closures >= 1  # the tour ends where it began
    end = scans[-1].truth
    assert math.dist(mapper.pose[:2], end[:2]) < 0.15


def test_scans_with_nan_inf_and_null_ranges_mark_nothing() -> None:
    message = {
        "angle_min": -math.pi,
        "angle_increment": math.pi / 2,
        "range_min": 0.1,
        "range_max": 8.0,
        "ranges": [1.0, None, float("nan"), float("inf")],
    }
    scan = Scan.from_message(message)
    assert np.isfinite(scan.ranges).sum() == 1
    assert len(scan.points()) == 1
    mapper = Mapper(SlamParams(min_beams=1))
    mapper.add((0.0, 0.0, 0.0), scan)
    grid, _ = mapper.grid()
    assert np.count_nonzero(grid == 100) == 1
    with pytest.raises(ValueError, match="no ranges"):
        Scan.from_message({"ranges": []})
    with pytest.raises(ValueError, match="angle_min"):
        Scan.from_message({"ranges": [1.0], "angle_min": "x", "angle_increment": 0.1})


def test_a_mapper_resumes_from_its_saved_state(tour) -> None:
    _, scans = tour
    half = len(scans) // 2
    first = mapped(scans[:half], Mapper(SlamParams(), start=scans[0].truth))
    again = Mapper.resumed(first.state())
    assert len(again.keyframes) == len(first.keyframes)
    assert np.array_equal(again.grid()[0], first.grid()[0])
    mapped(scans[half:], again)
    assert math.dist(again.pose[:2], scans[-1].truth[:2]) < 0.2
    with pytest.raises(ValueError, match="not a saved mapping state"):
        Mapper.resumed(b"junk")


def _wall_scan() -> Scan:
    """A scan of a room's walls 2 m around the robot, 180 beams."""
    angles = np.linspace(-math.pi, math.pi, 180, endpoint=False)
    return Scan(angles, np.full(180, 2.0))


def test_odometry_outside_the_sessions_extent_is_refused_and_the_map_stays_bounded() -> None:
    mapper = Mapper(SlamParams(), start=(1.0, 2.0, 0.0))
    mapper.add((0.0, 0.0, 0.0), _wall_scan())
    before = mapper.grid()[0].shape
    with pytest.raises(OutsideExtent, match=r"\(601.0, 602.0\).*within 50 m"):
        mapper.add((600.0, 600.0, 0.0), _wall_scan())
    assert mapper.grid()[0].shape == before
    assert mapper.stats.refused == 1
    mapper.add((0.0, 0.0, 1.0), _wall_scan())  # back where it is: mapped again
    assert mapper.stats.keyframes == 2
    assert math.dist(mapper.pose[:2], (1.0, 2.0)) < 0.2
    assert abs(mapper.pose[2] - 1.0) < 0.1


def test_a_resumed_mapper_keeps_the_extent_of_the_session() -> None:
    mapper = Mapper(SlamParams(), start=(30.0, 0.0, 0.0))
    mapper.add((0.0, 0.0, 0.0), _wall_scan())
    mapper.add((-20.0, 0.0, 0.0), _wall_scan())  # 20 m west of where the session started
    again = Mapper.resumed(mapper.state())
    again.add((0.0, 0.0, 0.0), _wall_scan())
    with pytest.raises(OutsideExtent):
        again.add((-35.0, 0.0, 0.0), _wall_scan())  # 55 m from the start, 35 m from here


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("ranges", [{"a": 1}, 1.0, 1.0]),
        ("ranges", ["1.0", 1.0, 1.0]),
        ("ranges", [True, 1.0, 1.0]),
        ("angle_increment", 1e308),  # the third beam's angle overflows
    ],
)
def test_a_scan_with_values_that_are_not_numbers_is_refused(field: str, value: object) -> None:
    message = {"angle_min": -1.0, "angle_increment": 0.01, "ranges": [1.0, 1.0, 1.0]}
    with pytest.raises(ValueError, match="scan"):
        Scan.from_message({**message, field: value})
