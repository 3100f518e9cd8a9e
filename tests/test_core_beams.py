"""The one beam traversal (``cloudnav_core.beams``): known beams through a small grid, in
cells (cell ``(row, col)`` covers ``col..col + 1`` by ``row..row + 1``)."""

from __future__ import annotations

import math

import numpy as np

from cloudnav_core.beams import Beams, first_solid, grid_point, traverse


def passed(gx: float, gy: float, angle: float, length: float) -> list[tuple[int, int]]:
    """The cells one beam passes through, in order."""
    out = traverse(Beams.towards(gx, gy, [angle]), np.array([length])).ordered()
    return list(zip(out.rows.tolist(), out.cols.tolist(), strict=True))


def test_an_axis_aligned_beam_passes_each_cell_of_its_row_in_order() -> None:
    out = traverse(Beams.towards(0.5, 0.5, [0.0]), np.array([3.2])).ordered()
    assert list(zip(out.rows.tolist(), out.cols.tolist(), strict=True)) == [
        (0, 0), (0, 1), (0, 2), (0, 3),
    ]  # fmt: skip
    assert np.allclose(out.enters, [0.0, 0.5, 1.5, 2.5])
    assert np.allclose(out.leaves, [0.5, 1.5, 2.5, 3.2])


def test_a_beam_heading_down_the_axes_passes_the_cells_below_and_left() -> None:
    assert passed(3.5, 2.5, math.pi, 2.0) == [(2, 3), (2, 2), (2, 1)]
    assert passed(0.5, 2.5, -math.pi / 2, 2.0) == [(2, 0), (1, 0), (0, 0)]


def test_a_diagonal_beam_through_corners_passes_the_diagonal_cells_only() -> None:
    # from (0.5, 0.5) at 45 degrees: corners (1, 1) and (2, 2), ends at (2.5, 2.5)
    assert passed(0.5, 0.5, math.pi / 4, 2 * math.sqrt(2)) == [(0, 0), (1, 1), (2, 2)]
    assert passed(2.5, 2.5, -3 * math.pi / 4, 2 * math.sqrt(2)) == [(2, 2), (1, 1), (0, 0)]


def test_a_beam_ends_in_the_cell_its_end_lies_in() -> None:
    # from (0.5, 0.5) towards (2.3, 1.4): crosses x = 1 at y 0.75, y = 1 at x 1.7, x = 2
    angle = math.atan2(0.9, 1.8)
    length = math.hypot(1.8, 0.9)
    assert passed(0.5, 0.5, angle, length) == [(0, 0), (0, 1), (1, 1), (1, 2)]
    out = traverse(Beams.towards(0.5, 0.5, [angle]), np.array([length])).ordered()
    assert out.leaves[-1] == length


def test_a_beam_of_length_zero_passes_its_start_cell() -> None:
    assert passed(1.25, 0.75, 1.0, 0.0) == [(0, 1)]


def test_beams_off_the_grid_list_cells_off_it_and_hit_nothing_there() -> None:
    assert passed(0.5, 0.5, math.pi, 2.0) == [(0, 0), (0, -1), (0, -2)]
    solid = np.zeros((3, 3), bool)
    hits = first_solid(solid, Beams.towards(1.5, 1.5, [0.0, math.pi]), 10.0)
    assert np.isinf(hits.t).all()


def test_every_beam_passes_the_cells_a_dense_walk_along_it_finds() -> None:
    rng = np.random.default_rng(3)
    angles = rng.uniform(-math.pi, math.pi, 50)
    lengths = rng.uniform(0.0, 12.0, 50)
    out = traverse(Beams.towards(4.3, 5.7, angles), lengths)
    for index, (angle, length) in enumerate(zip(angles, lengths, strict=True)):
        t = np.linspace(0.0, length, 20_000)
        walked = set(
            zip(
                np.floor(5.7 + t * math.sin(angle)).astype(int).tolist(),
                np.floor(4.3 + t * math.cos(angle)).astype(int).tolist(),
                strict=True,
            )
        )
        mine = out.beam == index
        listed = list(zip(out.rows[mine].tolist(), out.cols[mine].tolist(), strict=True))
        assert len(listed) == len(set(listed))  # each cell once
        assert set(listed) == walked


def test_each_cell_is_left_where_the_next_is_entered() -> None:
    rng = np.random.default_rng(4)
    lengths = rng.uniform(0.0, 9.0, 40)
    out = traverse(Beams.towards(2.6, 1.1, rng.uniform(-math.pi, math.pi, 40)), lengths)
    out = out.ordered()
    for index, length in enumerate(lengths):
        mine = out.beam == index
        assert np.allclose(out.leaves[mine][:-1], out.enters[mine][1:])
        assert out.enters[mine][0] == 0.0
        assert out.leaves[mine][-1] == length


def test_the_first_solid_cell_is_where_a_beam_enters_it() -> None:
    solid = np.zeros((4, 6), bool)
    solid[:, 4] = True  # a wall at x 4..5
    hits = first_solid(solid, Beams.towards(0.5, 1.5, [0.0, math.pi / 2]), 10.0)
    assert hits.t[0] == 3.5
    assert hits.cells[0].tolist() == [1, 4]
    assert hits.across_x[0]
    assert np.isinf(hits.t[1])  # up the free column and off the grid


def test_a_wall_beyond_reach_is_not_hit_and_a_beam_in_a_wall_hits_it_at_once() -> None:
    solid = np.zeros((4, 6), bool)
    solid[:, 4] = True
    assert np.isinf(first_solid(solid, Beams.towards(0.5, 1.5, [0.0]), 3.0).t[0])
    inside = first_solid(solid, Beams.towards(4.5, 1.5, [0.0, 2.0]), 3.0)
    assert inside.t.tolist() == [0.0, 0.0]
    assert inside.cells.tolist() == [[1, 4], [1, 4]]


def test_a_beam_through_a_corner_is_stopped_by_a_solid_cell_it_touches_there() -> None:
    # two solid cells meeting at corner (2, 2): the diagonal beam between them is stopped
    solid = np.zeros((4, 4), bool)
    solid[1, 2] = solid[2, 1] = True
    hits = first_solid(solid, Beams.towards(0.5, 0.5, [math.pi / 4]), 10.0)
    assert math.isclose(hits.t[0], 1.5 * math.sqrt(2))  # at corner (2, 2)
    assert tuple(hits.cells[0].tolist()) in {(1, 2), (2, 1)}


def test_grid_points_are_in_cells_from_the_grids_origin() -> None:
    assert grid_point((1.0, 2.0), (-1.0, 0.5), 0.5) == (4.0, 3.0)
