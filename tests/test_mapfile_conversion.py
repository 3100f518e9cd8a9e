"""Image to occupancy grid, by the rule docs/design.md states (Nav2's current map_io).

Boundary tests put a threshold exactly on a pixel's float32 occupancy p, or one float32
step either side of it, since that is where implementations disagree.
"""

from __future__ import annotations

import io
import time
import timeit

import numpy as np
import pytest
from PIL import Image

from maps.domain.mapfile import occupancy_from_image
from tests.support.mapfiles import (
    cell_of,
    cells_of,
    float32_step,
    make_image,
    make_meta,
    make_pgm,
    occupancy_of,
)

GREY = 89  # p = 0.65098..., near the usual occupied_thresh
P = occupancy_of(GREY)
THRESHOLD_MODES = ["trinary", "scale"]


# Occupied threshold


@pytest.mark.parametrize("mode", THRESHOLD_MODES)
def test_it_marks_pixels_at_occupied_thresh_as_occupied(mode: str) -> None:
    assert cell_of(GREY, mode=mode, occupied_thresh=P) == 100


@pytest.mark.parametrize("mode", THRESHOLD_MODES)
def test_it_marks_pixels_one_step_above_occupied_thresh_as_occupied(mode: str) -> None:
    assert cell_of(GREY, mode=mode, occupied_thresh=float32_step(P, -1)) == 100


def test_it_marks_pixels_one_step_below_occupied_thresh_as_unknown_in_trinary_mode() -> None:
    assert cell_of(GREY, occupied_thresh=float32_step(P, 1)) == -1


@pytest.mark.parametrize("mode", THRESHOLD_MODES)
def test_it_compares_occupied_thresh_as_a_float32(mode: str) -> None:
    # As a double, p is below this threshold; as a float32 it equals it.
    assert cell_of(GREY, mode=mode, occupied_thresh=P + 1e-12) == 100


# Free threshold


@pytest.mark.parametrize("mode", THRESHOLD_MODES)
def test_it_marks_pixels_at_free_thresh_as_free(mode: str) -> None:
    assert cell_of(GREY, mode=mode, free_thresh=P, occupied_thresh=0.9) == 0


@pytest.mark.parametrize("mode", THRESHOLD_MODES)
def test_it_marks_pixels_one_step_below_free_thresh_as_free(mode: str) -> None:
    assert cell_of(GREY, mode=mode, free_thresh=float32_step(P, 1), occupied_thresh=0.9) == 0


def test_it_marks_pixels_one_step_above_free_thresh_as_unknown_in_trinary_mode() -> None:
    assert cell_of(GREY, free_thresh=float32_step(P, -1), occupied_thresh=0.9) == -1


@pytest.mark.parametrize("mode", THRESHOLD_MODES)
def test_it_compares_free_thresh_as_a_float32(mode: str) -> None:
    assert cell_of(GREY, mode=mode, free_thresh=P - 1e-12, occupied_thresh=0.9) == 0


# Scale mode between the thresholds


def test_it_scales_a_pixel_one_step_inside_both_thresholds_to_50() -> None:
    free, occupied = float32_step(P, -1), float32_step(P, 1)
    assert cell_of(GREY, mode="scale", free_thresh=free, occupied_thresh=occupied) == 50


def test_it_scales_pixels_between_the_thresholds_linearly() -> None:
    image = make_image([[191, 127, 64]])  # p = 0.251, 0.502, 0.749
    expected = [round(100 * (1 - g / 255 - 0.25) / 0.5) for g in (191, 127, 64)]
    cells = cells_of(image, mode="scale", free_thresh=0.25, occupied_thresh=0.75)
    assert cells == [expected] == [[0, 50, 100]]


def test_it_rounds_scaled_halves_away_from_zero() -> None:
    # In float32, 100 (p - 0.1) / 0.8 is exactly 62.5 here: half to even would give 62.
    assert cell_of(102, mode="scale", free_thresh=0.1, occupied_thresh=0.9) == 63


def test_it_scales_from_the_float32_occupancy() -> None:
    # p(153) is 0.39999998 in float32 (0.4 exactly as a double, which would give 37.5 -> 38).
    assert cell_of(153, mode="scale", free_thresh=0.25, occupied_thresh=0.65) == 37


def test_it_scales_in_float32_arithmetic_as_nav2_does() -> None:
    # float32 gives exactly 62.5 -> 63; the same p scaled in doubles gives 62.49999 -> 62.
    assert cell_of(153, mode="scale", free_thresh=0.0, occupied_thresh=0.64) == 63


# Raw mode


@pytest.mark.parametrize("grey", [0, 1, 50, 99, 100])
def test_it_keeps_grey_bytes_up_to_100_in_raw_mode(grey: int) -> None:
    assert cell_of(grey, mode="raw") == grey


@pytest.mark.parametrize("grey", [101, 205, 254, 255])
def test_it_marks_grey_bytes_over_100_unknown_in_raw_mode(grey: int) -> None:
    assert cell_of(grey, mode="raw") == -1


def test_it_ignores_negate_and_thresholds_in_raw_mode() -> None:
    assert cell_of(30, mode="raw", negate=True, free_thresh=0.5, occupied_thresh=0.6) == 30


# Negate


@pytest.mark.parametrize("mode", THRESHOLD_MODES)
def test_it_treats_white_as_occupied_and_black_as_free_when_negated(mode: str) -> None:
    assert cells_of(make_image([[255, 0]]), mode=mode, negate=True) == [[100, 0]]


@pytest.mark.parametrize("mode", THRESHOLD_MODES)
def test_it_marks_negated_pixels_at_occupied_thresh_as_occupied(mode: str) -> None:
    p = occupancy_of(200, negate=True)
    assert cell_of(200, mode=mode, negate=True, occupied_thresh=p) == 100


def test_it_marks_negated_pixels_one_step_below_occupied_thresh_as_unknown() -> None:
    p = occupancy_of(200, negate=True)
    assert cell_of(200, negate=True, occupied_thresh=float32_step(p, 1)) == -1


@pytest.mark.parametrize("mode", THRESHOLD_MODES)
def test_it_marks_negated_pixels_at_free_thresh_as_free(mode: str) -> None:
    p = occupancy_of(40, negate=True)
    assert cell_of(40, mode=mode, negate=True, free_thresh=p) == 0


def test_it_marks_negated_pixels_one_step_above_free_thresh_as_unknown() -> None:
    p = occupancy_of(40, negate=True)
    assert cell_of(40, negate=True, free_thresh=float32_step(p, -1)) == -1


# Alpha


@pytest.mark.parametrize("mode", THRESHOLD_MODES)
def test_it_marks_pixels_with_alpha_below_255_unknown(mode: str) -> None:
    image = make_image([[(0, 0, 0, 255), (0, 0, 0, 254), (255, 255, 255, 0)]], "RGBA")
    assert cells_of(image, mode=mode) == [[100, -1, -1]]


@pytest.mark.parametrize("mode", THRESHOLD_MODES)
def test_it_marks_grey_pixels_with_alpha_below_255_unknown(mode: str) -> None:
    image = make_image([[(0, 255), (0, 254), (255, 1)]], "LA")
    assert cells_of(image, mode=mode) == [[100, -1, -1]]


def test_it_ignores_alpha_in_raw_mode() -> None:
    rgba = make_image([[(30, 30, 30, 0), (60, 60, 60, 128)]], "RGBA")
    la = make_image([[(30, 0), (60, 128)]], "LA")
    assert cells_of(rgba, mode="raw") == cells_of(la, mode="raw") == [[30, 60]]


@pytest.mark.parametrize("mode", THRESHOLD_MODES)
def test_it_marks_transparent_palette_entries_unknown(mode: str) -> None:
    image = Image.new("P", (2, 1))
    image.putpalette([0, 0, 0, 255, 255, 255])
    image.putdata([0, 1])
    image.info["transparency"] = 1
    assert cells_of(image, mode=mode) == [[100, -1]]


@pytest.mark.parametrize("mode", THRESHOLD_MODES)
def test_it_marks_the_transparent_grey_of_a_png_unknown(mode: str) -> None:
    buffer = io.BytesIO()
    make_image([[0, 254]]).save(buffer, "PNG", transparency=254)
    image = Image.open(buffer)
    assert cells_of(image, mode=mode) == [[100, -1]]


# Grey bytes of colour and wide images


LUMINANCE = [
    ((0, 12, 4), 8),  # 7.5 exactly: halves round up
    ((1, 23, 50), 20),  # 19.5 exactly
    ((255, 0, 0), 76),  # 76.245
    ((0, 0, 255), 29),  # 29.07
    ((0, 170, 0), 100),  # 99.79
    ((0, 171, 0), 100),  # 100.377
    ((0, 172, 0), -1),  # 100.964 rounds to 101, over raw's range
    ((100, 100, 100), 100),
]


@pytest.mark.parametrize(("rgb", "expected"), LUMINANCE, ids=[str(c[0]) for c in LUMINANCE])
def test_it_rounds_colour_luminance_to_the_nearest_byte(
    rgb: tuple[int, ...], expected: int
) -> None:
    assert cells_of(make_image([[rgb]], "RGB"), mode="raw") == [[expected]]


def test_it_takes_rgba_luminance_from_the_colour_bands() -> None:
    assert cells_of(make_image([[(1, 23, 50, 255)]], "RGBA"), mode="raw") == [[20]]


def test_it_uses_the_grey_byte_of_grey_images_as_it_is() -> None:
    assert cells_of(make_image([[37, 100, 101]]), mode="raw") == [[37, 100, -1]]


def test_it_reads_palette_images_by_the_luminance_of_their_colours() -> None:
    image = Image.new("P", (3, 1))
    image.putpalette([0, 12, 4, 40, 40, 40, 255, 0, 0])
    image.putdata([0, 1, 2])
    assert cells_of(image, mode="raw") == [[8, 40, 76]]


def test_it_reads_the_grey_band_of_grey_alpha_images() -> None:
    assert cells_of(make_image([[(60, 255), (7, 255)]], "LA"), mode="raw") == [[60, 7]]


def test_it_scales_16_bit_grey_to_the_nearest_byte() -> None:
    wide = np.array([[50 * 257, 50 * 257 + 128, 50 * 257 + 129, 0]], dtype=np.uint16)
    image = Image.fromarray(wide)
    assert image.mode == "I;16"
    assert cells_of(image, mode="raw") == [[50, 50, 51, 0]]


def test_it_reads_16_bit_pgms() -> None:
    data = b"P5\n3 1\n65535\n" + b"".join(v.to_bytes(2, "big") for v in (0, 65535, 257 * 99))
    image = Image.open(io.BytesIO(data))
    assert cells_of(image) == [[100, 0, -1]]
    assert cells_of(image, mode="raw") == [[0, -1, 99]]


def test_it_reads_1_bit_images_as_black_and_white() -> None:
    image = make_image([[0, 255]]).convert("1")
    assert cells_of(image) == [[100, 0]]


def test_it_reads_the_grey_of_32_bit_integer_images() -> None:
    image = Image.fromarray(np.array([[-5, 257 * 40, 70000]], dtype=np.int32))
    assert image.mode == "I"
    assert cells_of(image, mode="raw") == [[0, 40, -1]]


# Layout


def test_it_puts_the_image_bottom_row_first() -> None:
    image = make_image([[0, 0, 0], [254, 254, 254], [205, 205, 205]])
    assert cells_of(image) == [[-1, -1, -1], [0, 0, 0], [100, 100, 100]]


def test_it_keeps_columns_left_to_right() -> None:
    assert cells_of(make_image([[0, 254, 205]])) == [[100, 0, -1]]


def test_it_returns_int8_cells_shaped_height_by_width() -> None:
    grid = occupancy_from_image(make_image(np.zeros((3, 5))), make_meta())
    assert (grid.dtype, grid.shape) == (np.int8, (3, 5))
    assert grid.flags["C_CONTIGUOUS"]


# Maps saved by map_saver: 0 occupied, 205 unknown, 254 free


MAP_SAVER_ROW = [0, 205, 254]


def map_saver_cells(**kwargs: object) -> list[int]:
    image = Image.open(io.BytesIO(make_pgm([MAP_SAVER_ROW])))
    return cells_of(image, occupied_thresh=0.65, free_thresh=0.196, **kwargs)[0]


def strict_double_rule(grey: int) -> int:
    """ROS 1 map_server and older Nav2: doubles and strict comparisons."""
    p = 1.0 - grey / 255.0
    return 100 if p > 0.65 else 0 if p < 0.196 else -1


def test_it_loads_map_saver_pgms_as_occupied_unknown_free() -> None:
    assert map_saver_cells() == [100, -1, 0]


def test_it_loads_map_saver_pgms_as_the_older_strict_double_rule_does() -> None:
    assert map_saver_cells() == [strict_double_rule(g) for g in MAP_SAVER_ROW]


def test_it_loads_map_saver_unknown_grey_as_free_in_scale_mode() -> None:
    # 205 is p = 0.19608, just past free_thresh: scaled, that rounds to 0 under every rule.
    assert map_saver_cells(mode="scale") == [100, 0, 0]


def test_it_loads_map_saver_pgms_as_their_bytes_in_raw_mode() -> None:
    assert map_saver_cells(mode="raw") == [0, -1, -1]


# Speed


@pytest.mark.slow
@pytest.mark.parametrize(("mode", "bands"), [("L", 1), ("RGB", 3), ("RGBA", 4)])
def test_it_converts_a_4000_by_4000_map_in_under_a_second(mode: str, bands: int) -> None:
    pixels = np.random.default_rng(0).integers(0, 256, (4000, 4000, bands), dtype=np.uint8)
    image = Image.fromarray(pixels.squeeze(), mode)
    meta = make_meta(mode="scale")
    # Processor time: wall time on a loaded 2-core machine says more about the others. It
    # is 0.06 to 0.32 s on a quiet machine and up to 0.66 s while the other test worker shares
    # the cores and their caches, so the bound is the promise, a second.
    convert = lambda: occupancy_from_image(image, meta)  # noqa: E731
    seconds = min(timeit.repeat(convert, timer=time.process_time, number=1, repeat=3))
    assert seconds < 1.0
