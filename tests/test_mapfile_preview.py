"""What a dry-run upload answers: cell counts and a grid small enough to draw."""

from __future__ import annotations

import numpy as np

from maps.domain.mapfile import load_map_upload
from maps.domain.preview import cell_counts, downsampled, upload_preview
from tests.support.mapfiles import make_pgm, make_yaml


def test_it_counts_the_cells_of_each_kind() -> None:
    grid = np.array([[0, 0, 100], [-1, 42, 0]], dtype=np.int8)
    assert cell_counts(grid) == {"free": 3, "occupied": 1, "unknown": 1, "other": 1}


def test_a_small_grid_is_its_own_preview() -> None:
    grid = np.zeros((3, 4), dtype=np.int8)
    small, factor = downsampled(grid, max_side=4)
    assert factor == 1
    assert small is grid


def test_it_shrinks_by_a_whole_factor_until_both_sides_fit() -> None:
    small, factor = downsampled(np.zeros((10, 25), dtype=np.int8), max_side=8)
    assert factor == 4
    assert small.shape == (3, 7)


def test_a_thin_wall_survives_shrinking() -> None:
    grid = np.zeros((40, 40), dtype=np.int8)
    grid[:, 17] = 100
    small, factor = downsampled(grid, max_side=10)
    assert factor == 4
    assert (small[:, 4] == 100).all()
    assert (np.delete(small, 4, axis=1) == 0).all()


def test_unknown_wins_over_free_and_loses_to_any_other_value() -> None:
    grid = np.array([[0, -1, 0, -1], [0, 0, 1, 0]], dtype=np.int8)
    small, _ = downsampled(grid, max_side=2)
    assert small.tolist() == [[-1, 1]]


def test_a_partial_block_at_the_edge_shows_only_its_own_cells() -> None:
    grid = np.zeros((5, 5), dtype=np.int8)
    grid[4, 4] = -1
    small, factor = downsampled(grid, max_side=2)
    assert factor == 3
    assert small.tolist() == [[0, 0], [0, -1]]


def test_the_preview_is_an_occupancy_grid_at_the_coarser_resolution() -> None:
    pgm = make_pgm(np.full((30, 50), 254, dtype=np.uint8))
    loaded = load_map_upload(make_yaml(origin=[1.0, 2.0, 0.0]), {"map.pgm": pgm}, 10**6)
    document = upload_preview(loaded, "b/Lab", max_side=20)
    assert (document["width"], document["height"], document["preview_factor"]) == (50, 30, 3)
    assert document["counts"] == {"free": 1500, "occupied": 0, "unknown": 0, "other": 0}
    info = document["preview"]["info"]
    assert (info["width"], info["height"]) == (17, 10)
    assert info["resolution"] == document["resolution"] * 3
    assert info["origin"]["position"] == {"x": 1.0, "y": 2.0, "z": 0.0}
    assert document["preview"]["header"]["frame_id"] == "b/Lab"
    assert len(document["preview"]["data"]) == 17 * 10
