"""Opening uploaded image files: formats, damage, and size limits checked before decoding."""

from __future__ import annotations

import time
from typing import Any

import numpy as np
import pytest
from PIL import Image, ImageFile

from maps.domain.mapfile import open_map_image
from maps.exceptions import MapFileError
from tests.support.mapfiles import cells_of, encode, make_image, make_pgm, png_claiming

LIMIT = 10**6


def refusal(data: bytes, max_pixels: int = LIMIT) -> MapFileError:
    with pytest.raises(MapFileError) as caught:
        open_map_image(data, max_pixels)
    return caught.value


def blocks(*greys: int) -> Image.Image:
    """An image of 8x8 blocks side by side, one per grey value (JPEG keeps such blocks)."""
    return make_image(np.repeat(np.repeat([list(greys)], 8, axis=0), 8, axis=1))


def block_cells(image: Image.Image) -> list[int]:
    """The cell of each 8x8 block, left to right."""
    return cells_of(image)[0][::8]


LOSSLESS_FORMATS: list[tuple[str, dict[str, Any]]] = [
    ("PPM", {}),
    ("PNG", {}),
    ("BMP", {}),
    ("GIF", {}),
    ("TIFF", {}),
    ("TIFF", {"compression": "tiff_lzw"}),
]


@pytest.mark.parametrize(
    ("image_format", "params"), LOSSLESS_FORMATS, ids=[f"{f}{p}" for f, p in LOSSLESS_FORMATS]
)
def test_it_opens_each_lossless_image_format(image_format: str, params: dict[str, Any]) -> None:
    image = open_map_image(encode(blocks(0, 205, 254), image_format, **params), LIMIT)
    assert block_cells(image) == [100, -1, 0]


def test_it_opens_jpeg_images() -> None:
    image = open_map_image(encode(blocks(0, 255), "JPEG", quality=95), LIMIT)
    assert block_cells(image) == [100, 0]


def test_it_opens_colour_pngs() -> None:
    rgb = make_image(np.full((8, 8, 3), 40), "RGB")
    assert cells_of(open_map_image(encode(rgb), LIMIT), mode="raw")[0][0] == 40


def test_it_returns_the_image_with_its_pixels_loaded() -> None:
    image = open_map_image(make_pgm([[0, 254]]), LIMIT)
    assert image.im is not None
    assert image.size == (2, 1)


def test_it_refuses_a_truncated_png() -> None:
    data = encode(make_image(np.random.default_rng(1).integers(0, 256, (64, 64))))
    assert refusal(data[: len(data) // 2]).field == "image"


def test_it_refuses_a_png_whose_pixel_data_is_corrupt() -> None:
    data = bytearray(encode(make_image(np.random.default_rng(1).integers(0, 256, (64, 64)))))
    start = data.index(b"IDAT") + 8
    data[start : start + 64] = bytes(64)
    assert refusal(bytes(data)).field == "image"


def test_it_refuses_a_truncated_pgm() -> None:
    assert refusal(b"P5\n40 30\n255\n" + bytes(100)).field == "image"


def test_it_refuses_garbage_bytes() -> None:
    assert refusal(b"this is not an image at all").field == "image"


def test_it_refuses_empty_data() -> None:
    assert refusal(b"").field == "image"


def test_it_refuses_an_image_of_zero_pixels() -> None:
    assert refusal(b"P5\n0 30\n255\n").field == "image"


def test_it_refuses_formats_that_run_external_programs() -> None:
    eps = b"%!PS-Adobe-3.0 EPSF-3.0\n%%BoundingBox: 0 0 10 10\nshowpage\n"
    assert refusal(eps).field == "image"


def test_it_refuses_an_image_over_the_pixel_limit() -> None:
    error = refusal(make_pgm(np.zeros((100, 100))), max_pixels=9_999)
    assert error.field == "image"
    assert "100x100" in error.message


def test_it_accepts_an_image_at_the_pixel_limit() -> None:
    assert open_map_image(make_pgm(np.zeros((100, 100))), 10_000).size == (100, 100)


def test_it_checks_the_pixel_count_before_decoding(monkeypatch: pytest.MonkeyPatch) -> None:
    decoded: list[object] = []
    monkeypatch.setattr(ImageFile.ImageFile, "load", lambda image: decoded.append(image))
    error = refusal(png_claiming(8000, 8000))
    assert "8000x8000" in error.message
    assert decoded == []


@pytest.mark.parametrize(
    "header",
    [b"P5\n100000 100000\n255\n", png_claiming(100000, 100000)],
    ids=["pgm", "png"],
)
def test_it_refuses_a_header_claiming_100000_by_100000_without_decoding(header: bytes) -> None:
    started = time.process_time()
    assert refusal(header).field == "image"
    assert time.process_time() - started < 0.5


def test_it_refuses_what_pillow_calls_a_decompression_bomb() -> None:
    assert refusal(b"P5\n100000 100000\n255\n", max_pixels=10**12).field == "image"


def test_it_refuses_what_pillow_only_warns_about_as_a_decompression_bomb() -> None:
    assert refusal(b"P5\n10000 10000\n255\n", max_pixels=10**12).field == "image"
