"""Builders shared by the test_mapfile_* files (tests/test_mapfile_builders.py keeps them
honest).

The boundary tests build thresholds from a pixel's own 32-bit occupancy, so these
helpers must compute it exactly as the rule states: p = g / 255 in float32, 1 - p
unless negated.
"""

from __future__ import annotations

import io
import struct
import zipfile
import zlib
from typing import Any

import numpy as np
import yaml
from PIL import Image

from maps.domain.mapfile import MapMetadata, occupancy_from_image

MISSING = object()


def make_meta(**kwargs: Any) -> MapMetadata:
    kwargs.setdefault("image", "map.pgm")
    kwargs.setdefault("resolution", 0.05)
    kwargs.setdefault("origin", (0.0, 0.0, 0.0))
    kwargs.setdefault("occupied_thresh", 0.65)
    kwargs.setdefault("free_thresh", 0.196)
    kwargs.setdefault("negate", False)
    kwargs.setdefault("mode", "trinary")
    return MapMetadata(**kwargs)


def make_fields(**kwargs: Any) -> dict[str, Any]:
    """The keys of a map_server YAML; pass MISSING to leave a key out."""
    kwargs.setdefault("image", "map.pgm")
    kwargs.setdefault("resolution", 0.05)
    kwargs.setdefault("origin", [0.0, 0.0, 0.0])
    kwargs.setdefault("occupied_thresh", 0.65)
    kwargs.setdefault("free_thresh", 0.196)
    kwargs.setdefault("negate", 0)
    return {key: value for key, value in kwargs.items() if value is not MISSING}


def make_yaml(**kwargs: Any) -> bytes:
    return yaml.safe_dump(make_fields(**kwargs)).encode()


def make_image(rows: Any, mode: str = "L") -> Image.Image:
    """An image from rows of pixel values: ints for L, tuples for LA, RGB and RGBA."""
    return Image.fromarray(np.array(rows, dtype=np.uint8), mode)


def encode(image: Image.Image, image_format: str = "PNG", **params: Any) -> bytes:
    buffer = io.BytesIO()
    image.save(buffer, format=image_format, **params)
    return buffer.getvalue()


def make_pgm(rows: Any) -> bytes:
    return encode(make_image(rows), "PPM")


def cells_of(image: Image.Image, **kwargs: Any) -> list[list[int]]:
    """The occupancy grid of image under make_meta(**kwargs), as nested lists."""
    grid: list[list[int]] = occupancy_from_image(image, make_meta(**kwargs)).tolist()
    return grid


def cell_of(grey: int, **kwargs: Any) -> int:
    """The cell of a one-pixel grey image."""
    return cells_of(make_image([[grey]]), **kwargs)[0][0]


def occupancy_of(grey: int, negate: bool = False) -> float:
    """The float32 occupancy p of a grey byte, as the exact Python float."""
    shade = np.float32(grey) / np.float32(255)
    return float(shade if negate else np.float32(1) - shade)


def float32_step(value: float, steps: int) -> float:
    """The float32 that lies ``steps`` representable values above (or below) value."""
    result = np.float32(value)
    direction = np.float32(np.inf if steps > 0 else -np.inf)
    for _ in range(abs(steps)):
        result = np.nextafter(result, direction)
    return float(result)


def make_zip(members: dict[str, bytes]) -> bytes:
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w", zipfile.ZIP_DEFLATED) as archive:
        for name, data in members.items():
            archive.writestr(name, data)
    return buffer.getvalue()


def png_claiming(width: int, height: int) -> bytes:
    """A PNG whose header claims width x height grey pixels, holding two bytes of data."""
    header = struct.pack(">IIBBBBB", width, height, 8, 0, 0, 0, 0)
    pixels = zlib.compress(bytes(2))
    signature = b"\x89PNG\r\n\x1a\n"
    return signature + png_chunk(b"IHDR", header) + png_chunk(b"IDAT", pixels)


def png_chunk(kind: bytes, data: bytes) -> bytes:
    body = kind + data
    return struct.pack(">I", len(data)) + body + struct.pack(">I", zlib.crc32(body))
