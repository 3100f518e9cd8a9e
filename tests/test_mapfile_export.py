"""Exporting grids as map_server files, and grids as nav_msgs/OccupancyGrid messages."""

from __future__ import annotations

import io
import json
import math
from typing import Any

import numpy as np
import pytest
from PIL import Image

from maps.domain.mapfile import (
    MapMetadata,
    export_map,
    map_yaml_text,
    occupancy_from_image,
    occupancy_grid_message,
    open_map_image,
    parse_map_yaml,
)
from maps.exceptions import MapFileError
from tests.support.mapfiles import make_image, make_meta

TRINARY_GRID = np.array([[100, 0, -1], [0, 0, 100]], dtype=np.int8)


def reloaded(grid: np.ndarray, meta: MapMetadata | None = None) -> np.ndarray:
    """Export grid, then load the PGM back under the exported metadata."""
    pgm, exported = export_map(grid, meta or make_meta(), "out.pgm")
    return occupancy_from_image(open_map_image(pgm, 10**7), exported)


def exported_pixels(grid: np.ndarray) -> list[list[int]]:
    pgm, _ = export_map(grid, make_meta(), "out.pgm")
    pixels: list[list[int]] = np.asarray(Image.open(io.BytesIO(pgm))).tolist()
    return pixels


def random_scale_grid(seed: int) -> np.ndarray:
    return np.random.default_rng(seed).integers(-1, 101, (37, 53)).astype(np.int8)


# export_map


def test_it_exports_a_trinary_grid_as_a_binary_pgm() -> None:
    pgm, _ = export_map(TRINARY_GRID, make_meta(), "out.pgm")
    assert pgm.startswith(b"P5\n3 2\n255\n")
    assert len(pgm) == len(b"P5\n3 2\n255\n") + 6


def test_it_writes_trinary_cells_as_map_saver_greys() -> None:
    assert exported_pixels(np.array([[0, 100, -1]])) == [[254, 0, 205]]


def test_it_writes_the_bottom_row_of_the_grid_last() -> None:
    assert exported_pixels(np.array([[0, 0], [100, 100]])) == [[0, 0], [254, 254]]


def test_it_exports_a_trinary_grid_with_map_saver_metadata() -> None:
    _, meta = export_map(TRINARY_GRID, make_meta(negate=True, mode="scale"), "out.pgm")
    assert (meta.mode, meta.negate) == ("trinary", False)
    assert (meta.occupied_thresh, meta.free_thresh) == (0.65, 0.196)


def test_it_exports_any_other_grid_in_raw_mode() -> None:
    _, meta = export_map(np.array([[0, 50, -1]]), make_meta(negate=True), "out.pgm")
    assert (meta.mode, meta.negate) == ("raw", False)


def test_it_writes_raw_cells_as_their_values_and_unknown_as_255() -> None:
    assert exported_pixels(np.array([[0, 1, 99, 100, -1]])) == [[0, 1, 99, 100, 255]]


def test_it_keeps_resolution_and_origin() -> None:
    meta = make_meta(resolution=0.025, origin=(-12.5, 3.0, 0.7))
    for grid in (TRINARY_GRID, random_scale_grid(0)):
        _, exported = export_map(grid, meta, "out.pgm")
        assert (exported.resolution, exported.origin) == (0.025, (-12.5, 3.0, 0.7))


def test_it_names_the_image_in_the_exported_metadata() -> None:
    assert export_map(TRINARY_GRID, make_meta(image="in.png"), "CorridorA.pgm")[1].image == (
        "CorridorA.pgm"
    )


def test_it_treats_cells_outside_0_to_100_as_unknown() -> None:
    grid = np.array([[-5, 101, 127, -128, 100]], dtype=np.int8)
    assert reloaded(grid).tolist() == [[-1, -1, -1, -1, 100]]


@pytest.mark.parametrize(
    "grid",
    [
        np.zeros(5, np.int8),
        np.zeros((2, 2, 2), np.int8),
        np.zeros((0, 4), np.int8),
        np.zeros((2, 2)),
    ],
    ids=["1-D", "3-D", "empty", "float"],
)
def test_it_refuses_anything_but_a_non_empty_2d_integer_grid(grid: np.ndarray) -> None:
    with pytest.raises(MapFileError) as caught:
        export_map(grid, make_meta(), "out.pgm")
    assert caught.value.field == "grid"


# Round trips


def test_it_round_trips_a_trinary_grid() -> None:
    assert np.array_equal(reloaded(TRINARY_GRID), TRINARY_GRID)


@pytest.mark.parametrize("seed", range(5))
def test_it_round_trips_random_scale_grids(seed: int) -> None:
    grid = random_scale_grid(seed)
    assert np.array_equal(reloaded(grid), grid)


@pytest.mark.parametrize("seed", range(3))
def test_it_round_trips_grids_loaded_in_scale_mode(seed: int) -> None:
    rng = np.random.default_rng(seed)
    rgba = rng.integers(0, 256, (29, 41, 4), dtype=np.uint8)
    rgba[..., 3] = np.where(rng.random((29, 41)) < 0.1, 0, 255)
    meta = make_meta(mode="scale", free_thresh=0.1, occupied_thresh=0.9)
    grid = occupancy_from_image(make_image(rgba, "RGBA"), meta)
    assert np.array_equal(reloaded(grid, meta), grid)


def test_it_round_trips_grids_loaded_in_raw_mode() -> None:
    greys = np.random.default_rng(7).integers(0, 256, (20, 30))
    meta = make_meta(mode="raw")
    grid = occupancy_from_image(make_image(greys), meta)
    assert np.array_equal(reloaded(grid, meta), grid)


def test_it_round_trips_through_the_yaml_text() -> None:
    grid = random_scale_grid(11)
    pgm, meta = export_map(grid, make_meta(origin=(0.1 + 0.2, -7.25, 1.0)), "out.pgm")
    reread = parse_map_yaml(map_yaml_text(meta))
    assert reread == meta
    assert np.array_equal(occupancy_from_image(open_map_image(pgm, 10**7), reread), grid)


# occupancy_grid_message


def message(grid: np.ndarray | None = None, **kwargs: Any) -> dict[str, Any]:
    kwargs.setdefault("frame_id", "boccioni_1/CorridorA")
    meta = kwargs.pop("meta", None) or make_meta()
    return occupancy_grid_message(TRINARY_GRID if grid is None else grid, meta, **kwargs)


def test_it_builds_the_header_from_frame_and_stamp() -> None:
    header = message(stamp=(12, 500))["header"]
    assert header == {"stamp": {"sec": 12, "nanosec": 500}, "frame_id": "boccioni_1/CorridorA"}


def test_it_stamps_time_zero_unless_told() -> None:
    assert message()["header"]["stamp"] == {"sec": 0, "nanosec": 0}


def test_it_gives_the_stamp_as_the_map_load_time() -> None:
    assert message(stamp=(12, 500))["info"]["map_load_time"] == {"sec": 12, "nanosec": 500}


def test_it_describes_the_grid_size_and_resolution() -> None:
    info = message(meta=make_meta(resolution=0.1))["info"]
    assert (info["resolution"], info["width"], info["height"]) == (0.1, 3, 2)


def test_it_gives_the_origin_as_a_pose_with_the_yaw_as_a_quaternion() -> None:
    origin = message(meta=make_meta(origin=(-1.5, 2.0, math.pi / 2)))["info"]["origin"]
    assert origin["position"] == {"x": -1.5, "y": 2.0, "z": 0.0}
    quaternion = origin["orientation"]
    assert (quaternion["x"], quaternion["y"]) == (0.0, 0.0)
    assert quaternion["z"] == pytest.approx(math.sqrt(0.5))
    assert quaternion["w"] == pytest.approx(math.sqrt(0.5))


def test_it_lists_cells_row_by_row_from_the_bottom_row() -> None:
    grid = occupancy_from_image(make_image([[0, 0, 0], [254, 205, 254]]), make_meta())
    assert message(grid)["data"] == [0, -1, 0, 100, 100, 100]


def test_it_builds_a_message_that_serialises_as_json() -> None:
    assert json.loads(json.dumps(message()))["data"] == [100, 0, -1, 0, 0, 100]
