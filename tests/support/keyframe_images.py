"""Keyframe pictures built for the hostile-input tests: a progressive JPEG of as many scans
as asked."""

from __future__ import annotations

import io
import struct

import numpy as np
from PIL import Image as PILImage

from maps.domain.visual_input import jpeg_scans


def progressive_jpeg(scans: int, size: tuple[int, int] = (640, 480)) -> bytes:
    """A progressive JPEG of a flat grey picture whose last scan (a refinement of every
    AC coefficient, 12 bytes) is repeated until the file has ``scans`` scans: what the
    attack sent (50,000 scans in 785 KiB, within the pixel limit)."""
    out = io.BytesIO()
    PILImage.fromarray(np.full(size[::-1], 128, np.uint8)).save(out, "JPEG", progressive=True)
    data = out.getvalue()
    start, end = _last_scan(data)
    return data[:end] + data[start:end] * (scans - jpeg_scans(data)) + data[end:]


def _last_scan(data: bytes) -> tuple[int, int]:
    """Where the last scan (its header and entropy-coded data) starts and ends."""
    start = data.rindex(b"\xff\xda")
    end = start + 2 + struct.unpack(">H", data[start + 2 : start + 4])[0]
    while not (data[end] == 0xFF and data[end + 1] not in (0x00, *range(0xD0, 0xD8))):
        end += 1
    return start, end
