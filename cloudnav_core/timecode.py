"""A time code drawn into camera pictures, to measure glass-to-glass delay.

The camera writes the wall-clock time it took the picture (Unix milliseconds, modulo 2^42,
which wraps in 2109) as a strip of 42 black or white cells across the top of the image, most
significant bit first, under a row of alternating cells that lets a reader check the
strip is there. Cells are large (a 42nd of the width, at least 8 px high) and pure black
or white, so the code survives JPEG, VP8 and H.264 at the bitrates the relays use; a
reader thresholds each cell's mean at mid-grey. The same functions serve the simulated
camera, tests and benchmarks; the browser reads it with the same rule from a canvas.
"""

from __future__ import annotations

import numpy as np

BITS = 42
MODULO = 1 << BITS
ROWS = 2  # the check row, then the time row


class NoTimecode(ValueError):
    """The picture carries no readable time code."""


def cell_size(width: int, height: int) -> tuple[int, int]:
    """Return a cell's width and height in pixels for a picture of this size."""
    return width // BITS, max(8, height // 48)


def stamp(image: np.ndarray, millis: int) -> None:
    """Draw ``millis`` (modulo 2^42) into the top rows of a BGR or grey ``image``, in place."""
    height, width = image.shape[:2]
    cw, ch = cell_size(width, height)
    value = millis % MODULO
    for i in range(BITS):
        check = 255 if i % 2 == 0 else 0
        bit = 255 if (value >> (BITS - 1 - i)) & 1 else 0
        image[0:ch, i * cw : (i + 1) * cw] = check
        image[ch : 2 * ch, i * cw : (i + 1) * cw] = bit


def read(image: np.ndarray) -> int:
    """Return the milliseconds (modulo 2^42) stamped in a BGR, RGBA or grey ``image``.

    Raises NoTimecode when the check row does not alternate."""
    grey = image if image.ndim == 2 else image[..., :3].mean(axis=2)
    height, width = grey.shape[:2]
    cw, ch = cell_size(width, height)
    value = 0
    for i in range(BITS):
        # The middle of each cell only: codecs smear the edges.
        x0, x1 = i * cw + cw // 4, (i + 1) * cw - cw // 4
        check = grey[ch // 4 : ch - ch // 4, x0:x1].mean() > 128
        if check != (i % 2 == 0):
            raise NoTimecode(f"cell {i} of the check row is wrong")
        bit = grey[ch + ch // 4 : 2 * ch - ch // 4, x0:x1].mean() > 128
        value = (value << 1) | int(bit)
    return value


def delay_ms(stamped: int, now_millis: int) -> int:
    """Return how many milliseconds before ``now_millis`` a picture ``stamped`` was taken."""
    return (now_millis - stamped) % MODULO
