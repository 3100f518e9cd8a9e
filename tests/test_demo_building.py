"""The demo building: one consistent world, cut into sub-maps that line up, tagged both ways."""

from __future__ import annotations

import io
import math
import time
from collections import deque

import networkx as nx
import numpy as np
import numpy.typing as npt
import pytest
from PIL import Image

from maps.domain.demo_building import (
    FREE,
    OCCUPIED,
    PAPER_ROUTE,
    UNKNOWN,
    DemoBuilding,
    DemoSubMap,
    DemoTag,
    demo_building,
    doorway_openings,
    space_interiors,
    world_to_cell,
)
from maps.domain.widths import Widths

ROBOT_RADIUS = 0.2
FLEET_BENCH_ROBOTS = 10  # ``bench fleet``'s default --robots, the issue's fleet
STOP_DISTANCE = 0.4
HALF_CELL = 0.025
MAIN_ROUTE = list(PAPER_ROUTE)
GREY_TO_OCCUPANCY = {0: OCCUPIED, 254: FREE, 205: UNKNOWN}

Grid = npt.NDArray[np.int8]


@pytest.fixture(scope="module")
def building() -> DemoBuilding:
    return demo_building()


def decode(submap: DemoSubMap) -> Grid:
    """The sub-map's image as an occupancy grid, row 0 = bottom row."""
    image = Image.open(io.BytesIO(submap.pgm))
    grey = np.asarray(image)
    grid = np.full(grey.shape, 55, dtype=np.int8)  # 55: a grey no map_saver writes
    for level, value in GREY_TO_OCCUPANCY.items():
        grid[grey == level] = value
    return np.flipud(grid)


def offset_in_world(submap: DemoSubMap, building: DemoBuilding) -> tuple[int, int]:
    """(row, col) of the sub-map's cell (0, 0) in the world grid."""
    return world_to_cell(
        submap.origin[0] + HALF_CELL, submap.origin[1] + HALF_CELL, building.world_origin
    )


def overlap_cells(a: DemoSubMap, b: DemoSubMap, building: DemoBuilding) -> tuple[slice, slice]:
    """World (rows, cols) slices of the cells both sub-maps hold."""
    (ra, ca), (rb, cb) = offset_in_world(a, building), offset_in_world(b, building)
    rows = slice(max(ra, rb), min(ra + a.height, rb + b.height))
    cols = slice(max(ca, cb), min(ca + a.width, cb + b.width))
    return rows, cols


def cell_value(grid: Grid, origin: tuple[float, ...], x: float, y: float) -> int | None:
    """The grid's value at world point (x, y), or None outside the grid."""
    row, col = world_to_cell(x, y, origin)
    if not (0 <= row < grid.shape[0] and 0 <= col < grid.shape[1]):
        return None
    return int(grid[row, col])


def ahead(tag: DemoTag, distance: float) -> tuple[float, float]:
    return tag.x + distance * math.cos(tag.yaw), tag.y + distance * math.sin(tag.yaw)


def inside(submap: DemoSubMap, x: float, y: float) -> bool:
    ox, oy, _ = submap.origin
    return ox < x < ox + submap.width * submap.resolution and oy < y < oy + (
        submap.height * submap.resolution
    )


def neighbours(building: DemoBuilding) -> list[tuple[DemoSubMap, DemoSubMap]]:
    by_code = {submap.code: submap for submap in building.submaps}
    return [(by_code[edge.a], by_code[edge.b]) for edge in building.edges]


def inflated_free(world: Grid, radius: float, resolution: float) -> npt.NDArray[np.bool_]:
    """Cells whose centre is farther than ``radius`` from every cell that is not free."""
    blocked = world != FREE
    reach = math.floor(radius / resolution)
    padded = np.pad(blocked, reach, constant_values=True)
    grown = np.zeros_like(blocked)
    rows, cols = blocked.shape
    for dr in range(-reach, reach + 1):
        for dc in range(-reach, reach + 1):
            if dr * dr + dc * dc <= reach * reach:
                grown |= padded[reach + dr : reach + dr + rows, reach + dc : reach + dc + cols]
    return ~grown


def flood(free: npt.NDArray[np.bool_], start: tuple[int, int]) -> npt.NDArray[np.bool_]:
    """Cells reachable from ``start`` through 4-connected free cells."""
    seen = np.zeros_like(free)
    seen[start] = True
    queue = deque([start])
    while queue:
        row, col = queue.popleft()
        for r, c in ((row + 1, col), (row - 1, col), (row, col + 1), (row, col - 1)):
            if 0 <= r < free.shape[0] and 0 <= c < free.shape[1] and free[r, c] and not seen[r, c]:
                seen[r, c] = True
                queue.append((r, c))
    return seen


@pytest.fixture(scope="module")
def reachable(building: DemoBuilding) -> npt.NDArray[np.bool_]:
    free = inflated_free(building.world, ROBOT_RADIUS, building.resolution)
    start = world_to_cell(*building.start_pose[:2], building.world_origin)
    assert free[start], "the start pose must be clear of walls"
    return flood(free, start)


def test_it_names_the_building_of_the_paper(building: DemoBuilding) -> None:
    assert (building.code, building.name, building.zip_code) == (
        "boccioni_1",
        "Boccioni building, floor 1",
        "56037",
    )
    assert [s.code for s in building.submaps] == [
        "CorridorA",
        "Atrium1",
        "CorridorB",
        "CorridorC",
        "Atrium2",
        "CorridorD",
        "Atrium3",
        "Office7",
        "RoomA",
        "RoomB",
    ]


def test_the_world_grid_holds_only_occupancy_values_with_unknown_outside(
    building: DemoBuilding,
) -> None:
    world = building.world
    assert world.dtype == np.int8
    assert set(np.unique(world).tolist()) == {OCCUPIED, FREE, UNKNOWN}
    border = np.concatenate([world[0, :], world[-1, :], world[:, 0], world[:, -1]])
    assert (border == UNKNOWN).all()


def test_images_decode_as_8_bit_grey_with_map_saver_levels_only(building: DemoBuilding) -> None:
    for submap in building.submaps:
        image = Image.open(io.BytesIO(submap.pgm))
        assert (image.format, image.mode) == ("PPM", "L")
        assert image.size == (submap.width, submap.height)
        assert set(np.unique(np.asarray(image)).tolist()) <= {0, 205, 254}


def test_metadata_is_map_saver_trinary_in_the_world_frame(building: DemoBuilding) -> None:
    for submap in building.submaps:
        assert submap.resolution == building.resolution == 0.05
        assert submap.origin[2] == 0.0
        assert (submap.occupied_thresh, submap.free_thresh) == (0.65, 0.196)
        assert (submap.negate, submap.mode) == (0, "trinary")
        assert inside(submap, *submap.node_xy)


def test_every_submap_is_the_world_cut_at_its_origin(building: DemoBuilding) -> None:
    for submap in building.submaps:
        row, col = offset_in_world(submap, building)
        window = building.world[row : row + submap.height, col : col + submap.width]
        np.testing.assert_array_equal(decode(submap), window, err_msg=submap.code)


def test_neighbouring_submaps_overlap_and_agree_cell_for_cell(building: DemoBuilding) -> None:
    for a, b in neighbours(building):
        rows, cols = overlap_cells(a, b, building)
        # At least about 1.5 m both ways, so a tag in the overlap is in both maps.
        size = min(rows.stop - rows.start, cols.stop - cols.start) * a.resolution
        assert size >= 1.5, (a.code, b.code)
        in_a, in_b = (part_of(s, rows, cols, building) for s in (a, b))
        np.testing.assert_array_equal(in_a, in_b, err_msg=f"{a.code}/{b.code}")


def part_of(submap: DemoSubMap, rows: slice, cols: slice, building: DemoBuilding) -> Grid:
    """The decoded sub-map's cells at world cells ``rows, cols``."""
    row, col = offset_in_world(submap, building)
    return decode(submap)[rows.start - row : rows.stop - row, cols.start - col : cols.stop - col]


def test_marker_ids_are_unique_small_integers_from_zero(building: DemoBuilding) -> None:
    ids = sorted(tag.marker_id for tag in building.tags)
    assert ids == list(range(len(ids)))
    assert all(tag.size == 0.06 and 0.1 <= tag.height <= 0.6 for tag in building.tags)


def test_every_edge_has_a_tag_each_way_on_a_wall_in_both_maps(building: DemoBuilding) -> None:
    for a, b in neighbours(building):
        for here, there in ((a, b), (b, a)):
            tags = [t for t in building.tags if (t.submap, t.links_to) == (here.code, there.code)]
            assert len(tags) == 1, (here.code, there.code)
            for submap in (here, there):
                assert_tag_stands_on_a_wall(tags[0], submap)


def assert_tag_stands_on_a_wall(tag: DemoTag, submap: DemoSubMap) -> None:
    """Wall behind, free floor in front, and a stop 0.4 m out in free space, all in ``submap``."""
    grid, origin = decode(submap), submap.origin
    assert inside(submap, tag.x, tag.y), (tag, submap.code)
    assert cell_value(grid, origin, *ahead(tag, -HALF_CELL)) == OCCUPIED, (tag, submap.code)
    assert cell_value(grid, origin, *ahead(tag, HALF_CELL)) == FREE, (tag, submap.code)
    assert inside(submap, *ahead(tag, STOP_DISTANCE)), (tag, submap.code)
    assert cell_value(grid, origin, *ahead(tag, STOP_DISTANCE)) == FREE, (tag, submap.code)


def test_the_entrance_tag_leads_into_corridor_a_from_the_start_pose(
    building: DemoBuilding,
) -> None:
    entrance = [t for t in building.tags if t.submap == t.links_to]
    assert [(t.marker_id, t.submap) for t in entrance] == [(0, "CorridorA")]
    tag = entrance[0]
    corridor_a = building.submaps[0]
    assert_tag_stands_on_a_wall(tag, corridor_a)
    x, y, yaw = building.start_pose
    assert 1.0 <= math.dist((x, y), (tag.x, tag.y)) <= 1.5
    assert math.isclose(math.atan2(tag.y - y, tag.x - x), yaw, abs_tol=1e-9)
    assert inside(corridor_a, x, y)


def test_the_demo_robots_start_where_their_cameras_read_the_entrance_tag(
    building: DemoBuilding,
) -> None:
    # So `make demo`'s robots localise on their own instead of waiting, lost, for a goal.
    from cloudnav_core.camera import CameraModel
    from robots.agent.perception import TagDetector
    from robots.agent.sim.camera import Camera
    from robots.agent.sim.world import demo_world

    camera = Camera(demo_world(), CameraModel(), seed=11)
    detector = TagDetector(camera.model)
    corridor_a = building.submaps[0]
    assert len(building.robot_starts) >= 3
    for start in building.robot_starts:
        assert inside(corridor_a, *start[:2])
        cell = world_to_cell(*start[:2], building.world_origin)
        assert building.world[cell] == FREE, start
        read = [
            d.payload.map_code
            for _ in range(3)
            for d in detector.detect(camera.render(start))
            if d.marker_id == 0 and d.payload is not None
        ]
        assert read == ["CorridorA"] * 3, start


def test_the_demo_robots_start_clear_of_one_another(building: DemoBuilding) -> None:
    # Robots see and bump into one another: none may start touching another.
    from cloudnav_core.params import BodyLimits

    starts = building.robot_starts
    gaps = [math.dist(a[:2], b[:2]) for i, a in enumerate(starts) for b in starts[i + 1 :]]
    assert min(gaps) > 2 * BodyLimits().radius + 0.05


def test_there_is_a_parking_spot_for_every_robot_of_the_fleet_bench(
    building: DemoBuilding,
) -> None:
    names = [spot.name for spot in building.parking]
    assert len(names) >= max(FLEET_BENCH_ROBOTS, len(building.robot_starts))
    assert len(set(names)) == len(names)


def test_parking_spots_are_out_of_the_way_clear_of_walls_doorways_tags_and_each_other(
    building: DemoBuilding,
) -> None:
    widths = Widths.of_grid(building.world, building.world_origin, building.resolution)
    doorways = [((x0 + x1) / 2, (y0 + y1) / 2) for x0, y0, x1, y1 in doorway_openings().values()]
    interiors = space_interiors()
    spots = building.parking
    for spot in spots:
        here = (spot.x, spot.y)
        assert not spot.submap.startswith("Corridor"), spot
        x0, y0, x1, y1 = interiors[spot.submap][0]
        assert x0 < spot.x < x1, spot
        assert y0 < spot.y < y1, spot
        assert widths.clearance_at(here) >= 0.6, spot  # a robot and a margin, off furniture too
        assert min(math.dist(here, door) for door in doorways) >= 2.0, spot
        assert min(math.dist(here, (t.x, t.y)) for t in building.tags) >= 1.5, spot
    gaps = [math.dist((a.x, a.y), (b.x, b.y)) for i, a in enumerate(spots) for b in spots[i + 1 :]]
    assert min(gaps) >= 2.0


def test_the_cheapest_route_is_the_main_corridor_route(building: DemoBuilding) -> None:
    graph = nx.Graph()
    graph.add_edges_from((e.a, e.b, {"cost": e.cost}) for e in building.edges)
    assert nx.shortest_path(graph, "CorridorA", "Office7", weight="cost") == MAIN_ROUTE


def test_the_detour_through_room_b_is_real_but_dearer(building: DemoBuilding) -> None:
    graph = nx.Graph()
    graph.add_edges_from((e.a, e.b, {"cost": e.cost}) for e in building.edges)
    assert graph.has_edge("RoomB", "Atrium2")
    graph.remove_edge("CorridorC", "Atrium2")
    detour = nx.shortest_path(graph, "CorridorA", "Office7", weight="cost")
    assert detour == [*MAIN_ROUTE[:4], "RoomB", *MAIN_ROUTE[4:]]


def test_every_submaps_free_space_is_reachable_from_the_start_pose(
    building: DemoBuilding, reachable: npt.NDArray[np.bool_]
) -> None:
    free = inflated_free(building.world, ROBOT_RADIUS, building.resolution)
    # No pocket the robot could see but not reach: one connected free space.
    np.testing.assert_array_equal(reachable, free)
    metre = round(1 / building.resolution)
    for submap in building.submaps:
        row, col = world_to_cell(*submap.node_xy, building.world_origin)
        near_centre = reachable[row - metre : row + metre, col - metre : col + metre]
        assert near_centre.any(), submap.code


def test_the_stop_in_front_of_every_tag_is_reachable(
    building: DemoBuilding, reachable: npt.NDArray[np.bool_]
) -> None:
    for tag in building.tags:
        cell = world_to_cell(*ahead(tag, STOP_DISTANCE), building.world_origin)
        assert reachable[cell], tag


def test_furniture_leaves_paths_at_least_0_9_m_wide_between_all_tags(
    building: DemoBuilding,
) -> None:
    # A disc of 0.9 m diameter reaches 0.6 m in front of every tag from the start pose.
    wide = inflated_free(building.world, 0.45, building.resolution)
    start = world_to_cell(*building.start_pose[:2], building.world_origin)
    reachable = flood(wide, start)
    for tag in building.tags:
        assert reachable[world_to_cell(*ahead(tag, 0.6), building.world_origin)], tag


def test_every_doorway_can_be_crossed_0_9_m_wide_inside_the_overlap(
    building: DemoBuilding,
) -> None:
    # After reading a tag the robot switches maps and drives on in the new one: the way
    # from one tag's stop to the other's must lie where both maps see it.
    wide = inflated_free(building.world, 0.45, building.resolution)
    for a, b in neighbours(building):
        overlap = np.zeros_like(wide)
        overlap[overlap_cells(a, b, building)] = True
        tag_a = tag_between(building, a.code, b.code)
        tag_b = tag_between(building, b.code, a.code)
        start = world_to_cell(*ahead(tag_a, 0.6), building.world_origin)
        goal = world_to_cell(*ahead(tag_b, 0.6), building.world_origin)
        assert flood(wide & overlap, start)[goal], (a.code, b.code)


def tag_between(building: DemoBuilding, submap: str, links_to: str) -> DemoTag:
    return next(t for t in building.tags if (t.submap, t.links_to) == (submap, links_to))


def test_it_is_deterministic_and_fast() -> None:
    first = demo_building()
    timings = []
    for _ in range(3):
        demo_building.cache_clear()
        started = time.process_time()
        again = demo_building()
        timings.append(time.process_time() - started)
    assert min(timings) < 0.5
    assert again is not first
    assert again == first
    np.testing.assert_array_equal(again.world, first.world)
    assert demo_building() is again  # cached


def test_the_shared_world_grid_is_read_only(building: DemoBuilding) -> None:
    with pytest.raises(ValueError, match="read-only"):
        building.world[0, 0] = FREE


def test_cloud_location_changes_nothing_but_itself() -> None:
    other = demo_building("https://cloud.example.org")
    assert other.cloud_location == "https://cloud.example.org"
    assert other.submaps == demo_building().submaps
    assert other.tags == demo_building().tags
