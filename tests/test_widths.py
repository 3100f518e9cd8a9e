"""How wide the free space is (``maps.domain.widths``), the one measure the parking rule
(is a robot standing in a narrow place?) and right of way (where is a route too narrow for
two?) use, on the demo building's floor plan and on a drawn grid."""

from __future__ import annotations

import math

import numpy as np
import pytest

from maps.domain.demo_building import demo_building
from maps.domain.widths import REACH, Widths

DOORWAY = (17.9, 23.8)  # in the opening from Corridor A to Atrium 1, 1.2 m wide
CORRIDOR_A = [(12.0, 23.2), (12.0, 22.3), (12.0, 24.2), (5.0, 22.6), (15.0, 22.6)]  # 2.4 m
RESOLUTION = 0.05


@pytest.fixture(scope="module")
def building() -> Widths:
    plan = demo_building()
    return Widths.of_grid(np.asarray(plan.world), plan.world_origin[:2], plan.resolution)


def test_a_doorway_measures_its_opening(building):
    assert building.narrowest(DOORWAY) == pytest.approx(1.2, abs=0.06)


def test_a_corridor_measures_its_width_wherever_in_it_one_stands(building):
    for point in CORRIDOR_A:  # its middle and 0.2 to 0.35 m off either wall
        assert building.narrowest(point) == pytest.approx(2.4, abs=0.06), point


def corridor(width_m: float) -> Widths:
    """A grid 6 m long with a corridor ``width_m`` wide along x, walls one cell thick."""
    cells = round(width_m / RESOLUTION)
    grid = np.zeros((cells + 2, 120), dtype=np.int8)
    grid[0, :] = grid[-1, :] = 100
    return Widths.of_grid(grid, (0.0, 0.0), RESOLUTION)


def test_across_a_route_along_a_corridor_is_its_width_and_along_it_is_no_wider_than_reach():
    widths = corridor(1.0)
    middle, off_centre = (3.0, 0.55), (3.0, 0.3)
    assert widths.across(middle, 0.0, REACH) == pytest.approx(1.0, abs=0.06)
    assert widths.across(off_centre, 0.0, REACH) == pytest.approx(1.0, abs=0.06)
    # Going across the corridor, the line measured runs along it: its clearance is the
    # point's own, nowhere more.
    assert widths.across(off_centre, math.pi / 2, REACH) == pytest.approx(
        2 * widths.clearance_at(off_centre), abs=0.01
    )
    assert widths.narrowest(off_centre) == pytest.approx(1.0, abs=0.06)


def test_it_measures_nothing_in_a_wall_or_off_the_grid():
    widths = corridor(1.0)
    assert widths.narrowest((3.0, 0.02)) == 0.0
    assert widths.narrowest((-1.0, 0.5)) == 0.0
    assert widths.clearance_at((-1.0, 0.5)) == 0.0


def test_an_open_room_is_wider_than_two_reaches():
    room = Widths.of_grid(np.zeros((160, 160), dtype=np.int8), (0.0, 0.0), RESOLUTION)
    assert room.narrowest((4.0, 4.0)) > 2 * REACH
