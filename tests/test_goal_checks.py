"""Goals, waypoints and initial poses are checked against their sub-map's grid before a
robot drives: occupied, unknown, outside, too tight for the robot, or in a region no robot
can enter is refused with the reason (``maps.domain.planning.GoalCheck``)."""

from __future__ import annotations

import numpy as np
import numpy.typing as npt
import pytest

from maps.domain.planning import GoalCheck, PoseRefused, goal_check, inflate

RES = 0.05
RADIUS = 0.25


def room(entries: tuple[tuple[float, float], ...] = ((0.5, 1.5),)) -> GoalCheck:
    """A 4 x 3 m room walled round, a solid 0.4 m pillar at (2, 1.5), a walled closet
    (free inside) in the top-right corner, unknown cells in the bottom-right corner."""
    grid: npt.NDArray[np.int8] = np.zeros((60, 80), dtype=np.int8)
    grid[0, :] = grid[-1, :] = grid[:, 0] = grid[:, -1] = 100
    grid[26:34, 36:44] = 100  # the pillar
    grid[40:60, 60:62] = grid[40:42, 60:80] = 100  # the closet's walls
    grid[1:8, 72:79] = -1
    costmap = inflate(grid, RADIUS, RES)
    return goal_check(grid, costmap, entries)


def reason(
    point: tuple[float, float], entries: tuple[tuple[float, float], ...] = ((0.5, 1.5),)
) -> str:
    with pytest.raises(PoseRefused) as refused:
        room(entries).check(point)
    return refused.value.reason


def test_a_goal_in_open_floor_passes() -> None:
    room().check((1.0, 1.0))


def test_a_goal_beside_a_wall_passes_as_the_robot_snaps_it_free() -> None:
    room().check((0.15, 1.5))


def test_a_goal_on_a_pillar_is_refused_as_in_an_obstacle() -> None:
    assert reason((2.0, 1.5)) == "in an obstacle"


def test_a_goal_in_unknown_space_is_refused() -> None:
    assert reason((3.8, 0.2)) == "in unknown space"


@pytest.mark.parametrize("point", [(-0.1, 1.0), (4.1, 1.0), (1.0, 3.5), (float("nan"), 1.0)])
def test_a_goal_outside_the_map_is_refused(point: tuple[float, float]) -> None:
    assert reason(point) in ("outside the map", "not a finite point")


def test_a_goal_in_a_closed_room_is_refused_as_out_of_reach() -> None:
    assert reason((3.5, 2.6)) == "in a place no robot can reach from where it enters the map"


def test_without_entries_every_free_region_counts_as_reachable() -> None:
    room(entries=()).check((3.5, 2.6))


def test_a_gap_too_narrow_for_the_robot_is_refused() -> None:
    grid: npt.NDArray[np.int8] = np.full((40, 40), 100, dtype=np.int8)
    grid[5:35, 5:35] = 0
    grid[5:35, 19:21] = 0
    grid[5:35, 15:19] = grid[5:35, 21:25] = 100  # a 0.1 m slot between two walls
    check = goal_check(grid, inflate(grid, RADIUS, RES), ())
    with pytest.raises(PoseRefused, match="too near obstacles"):
        check.check((1.0, 1.0), tolerance=0.1)
