"""Planner speed: our planner beside networkx and scikit-image, and sub-maps against one map.

Part one plans corner to corner on a reproducible square grid (seeded random rectangles
and walls with gaps) with ``maps.domain.planning`` and with two references on the same
inflated grid: scikit-image's ``route_through_array`` (Dijkstra in Cython) and
networkx's ``astar_path`` (graph build timed apart). Part two is the paper's claim for
the demo building: hierarchical planning (the topology route, then a plan inside each
sub-map from where the robot enters to the tag leading on) against one plan on the
whole building's grid.

Run ``python manage.py bench planner`` or ``python -m benchmarks planner`` (``--help``).
Times exclude inflation (reported apart) and numba's one-off compile (reported apart).
"""

from __future__ import annotations

import argparse
import math
import statistics
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import networkx as nx
import numpy as np
import numpy.typing as npt
from skimage.graph import route_through_array

from cloudnav_core.grid import centre_of
from cloudnav_core.se2 import Point
from maps.domain import planning
from maps.domain.demo_building import DemoBuilding, DemoTag, demo_building, submap_grid
from maps.domain.obstacle_course import obstacle_course
from maps.domain.topology import Edge, RouteStep, TagLink, route_between

Grid = npt.NDArray[np.int8]
Cells = list[tuple[int, int]]

GOAL_SUBMAP = "Office7"
TAG_STANDOFF = 0.6
"""Metres in front of a tag where a leg of the hierarchical plan ends."""
GRADIENT_M = 0.5
"""The wall gradient of the costmaps planned by A* (JPS needs uniform costs)."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Declare the benchmark's options on ``parser``."""
    parser.add_argument("--size", type=int, default=1000, help="grid side in cells")
    parser.add_argument("--seed", type=int, default=7, help="seed of the obstacle course")
    parser.add_argument("--repeat", type=int, default=21, help="timed runs of our planner")
    parser.add_argument("--resolution", type=float, default=0.05, help="metres per cell")
    parser.add_argument("--radius", type=float, default=0.2, help="robot radius, metres")
    parser.add_argument(
        "--skip-networkx", action="store_true", help="skip networkx (about 10 s and 1 GB)"
    )


def run(options: argparse.Namespace | Mapping[str, Any]) -> None:
    """Print both parts of the benchmark; ``options`` as ``add_arguments`` declares them."""
    opts = argparse.Namespace(**options) if isinstance(options, Mapping) else options
    started = time.perf_counter()
    planning.warm_up()
    print(f"numba compile or cache load (first call, not counted): {_ms(started)} ms\n")
    _grid_benchmark(opts)
    print()
    _building_benchmark(opts)


# ---------------------------------------------------------------------------------------
# Part one: corner to corner on an obstacle course


@dataclass(frozen=True)
class Timed:
    """Times in seconds of repeated runs, and the path length in metres of the last."""

    times: list[float]
    length: float

    def line(self, name: str, optimum: float) -> str:
        median = statistics.median(self.times) * 1000
        p90 = float(np.percentile(self.times, 90)) * 1000
        ratio = self.length / optimum
        return f"{name:<40} {median:>10.1f} {p90:>10.1f} {self.length:>9.2f} m {ratio:>7.3f}"


def _grid_benchmark(opts: argparse.Namespace) -> None:
    grid = obstacle_course(opts.size, opts.seed)
    res, corner = opts.resolution, opts.size - 1
    start, goal = centre_of((0, 0), (0, 0), res), centre_of((corner, corner), (0, 0), res)
    inflating = _timed(lambda: planning.inflate(grid, opts.radius, res), 5)
    plain = planning.inflate(grid, opts.radius, res)
    graded = planning.inflate(grid, opts.radius, res, gradient_m=GRADIENT_M)
    print(f"{opts.size}x{opts.size} grid, seed {opts.seed}, {res} m/cell, radius {opts.radius} m")
    print(f"inflation (OpenCV distance transform): {statistics.median(inflating) * 1000:.1f} ms")
    reference = _skimage(plain.blocked, res)
    rows = [
        ("ours: JPS + line-of-sight shortcut", _ours(plain, start, goal, opts.repeat)),
        (f"ours: A* with a {GRADIENT_M} m wall gradient", _ours(graded, start, goal, 5)),
        ("scikit-image route_through_array", reference),
    ]
    if not opts.skip_networkx:
        rows.append(("networkx astar_path", _networkx(plain.blocked, res)))
    print(f"{'planner':<40} {'median ms':>10} {'p90 ms':>10} {'length':>11} {'/ skimage':>7}")
    for name, timed in rows:
        print(timed.line(name, reference.length))


def _ours(costmap: planning.Costmap, start: Point, goal: Point, repeat: int) -> Timed:
    path: list[Point] = []

    def plan() -> None:
        path[:] = planning.plan_on(costmap, start, goal)

    times = _timed(plan, repeat)
    return Timed(times, planning.path_length(path))


def _skimage(blocked: npt.NDArray[np.bool_], resolution: float) -> Timed:
    """scikit-image's minimum-cost path, unit cost per cell; negative costs are walls."""
    costs = np.where(blocked, -1.0, 1.0)
    corner = blocked.shape[0] - 1
    cells: Cells = []

    def plan() -> None:
        found, _ = route_through_array(costs, (0, 0), (corner, corner), geometric=True)
        cells[:] = found

    times = _timed(plan, 3)
    return Timed(times, _cells_length(cells, resolution))


def _networkx(blocked: npt.NDArray[np.bool_], resolution: float) -> Timed:
    """networkx A* on the 8-connected graph of free cells (no corner cutting, as ours)."""
    started = time.perf_counter()
    graph = _grid_graph(blocked)
    print(f"networkx graph build (not in its time below): {_ms(started)} ms")
    width, corner = blocked.shape[1], blocked.size - 1

    def octile(a: int, b: int) -> float:
        rows, cols = abs(a // width - b // width), abs(a % width - b % width)
        return float(max(rows, cols) + (math.sqrt(2) - 1) * min(rows, cols))

    nodes: list[int] = []

    def plan() -> None:
        nodes[:] = nx.astar_path(graph, 0, corner, heuristic=octile, weight="weight")

    times = _timed(plan, 1)
    return Timed(times, _cells_length([divmod(node, width) for node in nodes], resolution))


def _grid_graph(blocked: npt.NDArray[np.bool_]) -> nx.Graph:
    """The free cells as nodes (flat index), joined by weighted 8-connected steps."""
    free = ~blocked
    height, width = blocked.shape
    index = np.arange(blocked.size).reshape(blocked.shape)
    graph = nx.Graph()
    graph.add_nodes_from(index[free].tolist())
    for dr, dc in ((0, 1), (1, 0), (1, 1), (1, -1)):
        rows, cols = slice(0, height - dr), slice(max(-dc, 0), width - max(dc, 0))
        to_rows, to_cols = slice(dr, height), slice(max(dc, 0), width - max(-dc, 0))
        ok = free[rows, cols] & free[to_rows, to_cols]
        if dr and dc:  # no corner cutting: both cells beside the diagonal free
            ok &= free[to_rows, cols] & free[rows, to_cols]
        weight = math.sqrt(2) if dr and dc else 1.0
        pairs = zip(
            index[rows, cols][ok].tolist(), index[to_rows, to_cols][ok].tolist(), strict=True
        )
        graph.add_weighted_edges_from((a, b, weight) for a, b in pairs)
    return graph


def _cells_length(cells: Cells, resolution: float) -> float:
    return planning.path_length([(float(c), float(r)) for r, c in cells]) * resolution


# ---------------------------------------------------------------------------------------
# Part two: the demo building, sub-map by sub-map against the whole building


@dataclass(frozen=True)
class Leg:
    """One plan of part two: a grid, its frame, where it starts and where it ends."""

    grid: Grid
    resolution: float
    origin: Sequence[float]
    start: Point
    goal: Point


def _building_benchmark(opts: argparse.Namespace) -> None:
    building = demo_building()
    started = time.perf_counter()
    route = _route(building)
    route_ms = _ms(started)
    legs = _legs(building, route)
    start, goal = legs[0].start, legs[-1].goal
    world = Leg(building.world, building.resolution, building.world_origin, start, goal)
    print(f"Demo building: {' -> '.join(step.submap for step in route)}")
    print(f"topology route (networkx, once, not in the sums below): {route_ms} ms")
    print(f"{'median ms (sum over sub-maps)':<34} {'sub-maps':>9} {'whole':>9} {'ratio':>6}")
    for name, gradient in (("JPS", 0.0), (f"A*, {GRADIENT_M} m gradient", GRADIENT_M)):
        hierarchical = [_plan_leg(leg, opts, gradient) for leg in legs]
        whole = _plan_leg(world, opts, gradient)
        for what, index in (("inflate", 0), ("plan", 1)):
            parts = sum(result[index] for result in hierarchical)
            print(
                f"{what + ', ' + name:<34} {parts:>9.2f} {whole[index]:>9.2f} "
                f"{whole[index] / parts:>6.1f}"
            )
        length = sum(result[2] for result in hierarchical)
        print(f"{'path length m, ' + name:<34} {length:>9.1f} {whole[2]:>9.1f}")


def _plan_leg(leg: Leg, opts: argparse.Namespace, gradient: float) -> tuple[float, float, float]:
    """Return the median inflation and planning times (ms) of ``leg``, and its length."""
    costmaps: list[planning.Costmap] = []

    def inflate() -> None:
        costmaps[:] = [
            planning.inflate(
                leg.grid, opts.radius, leg.resolution, origin=leg.origin, gradient_m=gradient
            )
        ]

    inflating = statistics.median(_timed(inflate, 5)) * 1000
    timed = _ours(costmaps[0], leg.start, leg.goal, opts.repeat)
    return inflating, statistics.median(timed.times) * 1000, timed.length


def _route(building: DemoBuilding) -> list[RouteStep]:
    nodes = [submap.code for submap in building.submaps]
    edges = [Edge(edge.a, edge.b, edge.cost) for edge in building.edges]
    tags = [TagLink(tag.marker_id, tag.submap, tag.links_to) for tag in building.tags]
    return route_between(nodes, edges, tags, building.submaps[0].code, GOAL_SUBMAP)


def _legs(building: DemoBuilding, route: Sequence[RouteStep]) -> list[Leg]:
    """Each sub-map from where the robot enters to the tag leading on (or the goal).

    A leg ends in front of its tag, in the overlap of the two sub-maps, so the next leg
    starts there in the next sub-map's frame (every sub-map shares the world frame).
    """
    submaps = {submap.code: submap for submap in building.submaps}
    tags = {tag.marker_id: tag for tag in building.tags}
    here: Point = building.start_pose[:2]
    legs = []
    for step in route:
        submap = submaps[step.submap]
        goal = _in_front(tags[step.tag.marker_id]) if step.tag else submap.node_xy
        legs.append(Leg(submap_grid(submap), submap.resolution, submap.origin, here, goal))
        here = goal
    return legs


def _in_front(tag: DemoTag) -> Point:
    return tag.x + TAG_STANDOFF * math.cos(tag.yaw), tag.y + TAG_STANDOFF * math.sin(tag.yaw)


# ---------------------------------------------------------------------------------------


def _timed(action: Callable[[], object], repeat: int) -> list[float]:
    times = []
    for _ in range(repeat):
        started = time.perf_counter()
        action()
        times.append(time.perf_counter() - started)
    return times


def _ms(started: float) -> str:
    return f"{(time.perf_counter() - started) * 1000:.0f}"
