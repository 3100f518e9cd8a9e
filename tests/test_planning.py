"""The global planner: inflation, exact grid search, shortcuts, frames and errors."""

from __future__ import annotations

import math
from itertools import pairwise

import numpy as np
import numpy.typing as npt
import pytest
from skimage.graph import route_through_array

from benchmarks.planner import run as run_benchmark
from cloudnav_core.grid import cell_of, centre_of
from cloudnav_core.se2 import Point
from maps.domain import planning
from maps.domain.demo_building import demo_building, submap_grid
from maps.domain.obstacle_course import obstacle_course
from maps.domain.planning import (
    Costmap,
    InObstacleError,
    NoPathError,
    OutOfMapError,
    inflate,
    path_length,
    plan_on,
    plan_path,
)

Grid = npt.NDArray[np.int8]
RES = 0.05


def empty(height: int = 60, width: int = 60) -> Grid:
    return np.zeros((height, width), dtype=np.int8)


def wall_with_gap(rows: slice = slice(25, 35)) -> Grid:
    """A 60 x 60 grid cut by a wall along column 30, open at ``rows``."""
    grid = empty()
    grid[:, 30:32] = 100
    grid[rows, 30:32] = 0
    return grid


def samples(path: list[Point], step: float = RES / 4) -> list[Point]:
    """Points every ``step`` metres along each segment, ends included."""
    points = []
    for (x0, y0), (x1, y1) in pairwise(path):
        count = max(1, math.ceil(math.dist((x0, y0), (x1, y1)) / step))
        points += [(x0 + (x1 - x0) * i / count, y0 + (y1 - y0) * i / count) for i in range(count)]
    return [*points, path[-1]]


def assert_clear(costmap: Costmap, path: list[Point]) -> None:
    for point in samples(path):
        cell = cell_of(point, costmap.origin, costmap.resolution)
        assert not costmap.blocked[cell], f"{point} is in blocked cell {cell}"


def test_it_plans_a_straight_line_in_an_empty_grid() -> None:
    path = plan_path(empty(), (0.3, 0.3), (2.7, 2.2), RES, (0.0, 0.0))
    assert path == [centre_of((6, 6), (0, 0), RES), centre_of((44, 54), (0, 0), RES)]


def test_it_returns_one_point_when_start_and_goal_share_a_cell() -> None:
    path = plan_path(empty(), (1.01, 1.01), (1.04, 1.02), RES, (0, 0))
    assert path == [centre_of((20, 20), (0, 0), RES)]


def test_it_goes_around_a_wall_through_its_gap() -> None:
    costmap = inflate(wall_with_gap(), 0.1, RES)
    path = plan_on(costmap, (0.5, 0.3), (2.5, 0.3))
    assert_clear(costmap, path)
    crossing = [y for x, y in samples(path) if 1.5 <= x <= 1.6]
    assert crossing
    assert all(1.25 + 0.1 <= y <= 1.75 - 0.1 for y in crossing)


def test_no_point_of_the_path_comes_within_the_robot_radius_of_an_obstacle() -> None:
    grid = obstacle_course(300, seed=3)
    costmap = inflate(grid, 0.2, RES)
    path = plan_on(costmap, (0.1, 0.1), (14.9, 14.9))
    assert_clear(costmap, path)
    obstacles = np.argwhere(grid >= 65)
    for x, y in samples(path):
        nearest = np.hypot(obstacles[:, 1] + 0.5 - x / RES, obstacles[:, 0] + 0.5 - y / RES).min()
        # Cell centres are kept a radius apart; a point may sit up to half a cell off one.
        assert nearest * RES > 0.2 - RES * math.sqrt(0.5)


def test_unknown_cells_are_obstacles_by_default() -> None:
    grid = wall_with_gap()
    grid[grid == 100] = -1
    costmap = inflate(grid, 0.1, RES)
    assert len(plan_on(costmap, (0.5, 0.3), (2.5, 0.3))) > 2
    seen_through = plan_path(grid, (0.5, 0.3), (2.5, 0.3), RES, (0, 0), unknown_is_obstacle=False)
    assert len(seen_through) == 2


def test_a_gradient_keeps_the_path_further_from_walls() -> None:
    grid = empty(40, 200)
    grid[:2, :] = grid[-2:, :] = 100
    start, goal = (0.5, 0.35), (9.5, 0.35)
    hugging = plan_path(grid, start, goal, RES, (0, 0), 0.2)
    costmap = inflate(grid, 0.2, RES, gradient_m=0.6, gradient_weight=3.0)
    kept_off = plan_on(costmap, start, goal)
    assert_clear(costmap, kept_off)
    mid_y = [y for x, y in samples(kept_off) if 4.0 <= x <= 6.0]
    assert min(mid_y) > max(y for x, y in samples(hugging) if 4.0 <= x <= 6.0) + 0.2


def test_a_start_in_an_obstacle_moves_to_the_nearest_free_cell() -> None:
    grid = wall_with_gap()
    path = plan_path(grid, (1.5, 0.4), (2.5, 0.4), RES, (0, 0), 0.1, tolerance=0.3)
    # Inflated by 0.1 m, columns 28..33 are blocked: the nearest free cell is 3 cells west.
    assert path[0] == centre_of((8, 27), (0, 0), RES)


@pytest.mark.parametrize("which", ["start", "goal"])
def test_an_endpoint_in_an_obstacle_beyond_tolerance_raises(which: str) -> None:
    grid = empty()
    grid[:, 20:40] = 100
    far, blocked = (0.3, 0.3), (1.5, 1.5)
    start, goal = (blocked, far) if which == "start" else (far, blocked)
    with pytest.raises(InObstacleError) as caught:
        plan_path(grid, start, goal, RES, (0, 0), tolerance=0.3)
    assert caught.value.which == which


@pytest.mark.parametrize(
    ("start", "goal", "which"),
    [
        ((-0.01, 1.0), (1.0, 1.0), "start"),
        ((1.0, 1.0), (1.0, 3.0), "goal"),
        ((1.0, 1.0), (math.nan, 1.0), "goal"),
    ],
)
def test_an_endpoint_outside_the_map_raises(start: Point, goal: Point, which: str) -> None:
    with pytest.raises(OutOfMapError) as caught:
        plan_path(empty(), start, goal, RES, (0, 0))
    assert caught.value.which == which


@pytest.mark.parametrize("gradient_m", [0.0, 0.5])
def test_an_unreachable_goal_raises_no_path_error(gradient_m: float) -> None:
    grid = wall_with_gap(rows=slice(0, 0))
    costmap = inflate(grid, 0.2, RES, gradient_m=gradient_m)
    with pytest.raises(NoPathError):
        plan_on(costmap, (0.5, 1.5), (2.5, 1.5))


@pytest.mark.parametrize("seed", [3, 4, 5])
def test_paths_are_within_two_percent_of_the_optimum_on_random_maps(seed: int) -> None:
    grid = obstacle_course(300, seed)
    costmap = inflate(grid, 0.2, RES)
    costs = np.where(costmap.blocked, -1.0, 1.0)
    corner = grid.shape[0] - 1
    _, optimum = route_through_array(costs, (0, 0), (corner, corner), geometric=True)
    goal = centre_of((corner, corner), (0, 0), RES)
    length = path_length(plan_on(costmap, (0.0, 0.0), goal)) / RES
    # Shortcuts only shorten the exact grid path, and scikit-image may cut corners.
    assert length <= optimum * 1.02
    assert length >= optimum * 0.9


def test_jump_point_search_finds_paths_as_cheap_as_a_star() -> None:
    rng = np.random.default_rng(11)
    for _ in range(200):
        size = int(rng.integers(4, 40))
        blocked = rng.random((size, size)) < rng.uniform(0.05, 0.45)
        free = np.zeros((size + 2, size + 2), dtype=np.uint8)
        free[1:-1, 1:-1] = ~blocked
        cells = np.flatnonzero(free)
        if cells.size < 2:
            continue
        a, b = (int(cell) for cell in rng.choice(cells, 2, replace=False))
        flat, stride = free.ravel(), size + 2
        jumps = planning._jump_point_search(flat, stride, a, b)
        steps = planning._astar(flat, np.zeros(flat.size, np.float32), stride, a, b)
        if steps.size == 0:
            assert jumps.size == 0
        else:
            assert _cost(jumps, stride) == pytest.approx(_cost(steps, stride), abs=1e-9)


def _cost(cells: npt.NDArray[np.int64], stride: int) -> float:
    return path_length([(float(c % stride), float(c // stride)) for c in cells])


def test_it_takes_and_gives_metres_in_the_map_frame() -> None:
    grid = wall_with_gap()
    in_cells = plan_path(grid, (10.5, 2.5), (50.5, 2.5), 1.0, (0, 0), 2.0)
    origin, resolution = (-3.0, 7.5, 0.0), 0.1
    in_metres = plan_path(grid, (-1.95, 7.75), (2.05, 7.75), resolution, origin, 0.2)
    expected = [(origin[0] + x * resolution, origin[1] + y * resolution) for x, y in in_cells]
    assert np.allclose(in_metres, expected, rtol=0, atol=1e-9)


def test_a_demo_sub_map_is_crossed_from_its_entry_to_the_tag_leading_on() -> None:
    building = demo_building()
    corridor = next(submap for submap in building.submaps if submap.code == "CorridorA")
    tag = next(t for t in building.tags if (t.submap, t.links_to) == ("CorridorA", "Atrium1"))
    goal = (tag.x + 0.6 * math.cos(tag.yaw), tag.y + 0.6 * math.sin(tag.yaw))
    costmap = inflate(submap_grid(corridor), 0.2, corridor.resolution, origin=corridor.origin)
    path = plan_on(costmap, building.start_pose[:2], goal)
    assert_clear(costmap, path)
    assert math.dist(path[0], building.start_pose[:2]) < corridor.resolution
    assert math.dist(path[-1], goal) < corridor.resolution


@pytest.mark.parametrize("resolution", [1.0, 0.1, 0.05, 0.03])
def test_inflation_blocks_the_cells_exactly_a_radius_away_at_any_resolution(
    resolution: float,
) -> None:
    grid = empty(11, 11)
    grid[5, 5] = 100
    blocked = inflate(grid, 3 * resolution, resolution).blocked
    assert blocked[5, 8]
    assert blocked[5, 2]
    assert blocked[8, 5]
    assert not blocked[5, 9]  # 4 cells away
    assert not blocked[7, 8]  # sqrt(13) cells away


@pytest.mark.slow
def test_the_planner_benchmark_runs_on_a_small_grid(capsys: pytest.CaptureFixture[str]) -> None:
    options = {"size": 300, "seed": 3, "repeat": 1, "resolution": RES, "radius": 0.2}
    run_benchmark({**options, "skip_networkx": False})
    printed = capsys.readouterr().out
    assert "networkx astar_path" in printed
    assert "plan, JPS" in printed
