"""Tag reading range in the simulated camera: the paper's Tables 1 and 2, reproduced.

For each marker size (2, 4, 6, 8 cm), QR version (3, 4, 8) and view angle (0, 30, 45,
60 degrees off the tag's normal), the largest distance at which the rendered camera
still finds the marker, and still decodes the QR code, with the robot's own detector
(``TagDetector``: ArUco + IPPE, zxing-cpp on the QR beside the marker).

Setup: one tag on a long straight wall, its codes at the camera's height; the camera
stands ``distance`` metres from the centre of the code under test (marker or QR), on a
line ``angle`` degrees off the tag's normal toward the QR side, and looks at that
centre. A QR payload of version v is the demo payload padded until it no longer fits
version v - 1 (level L), so the code has exactly that many modules.

Search: a distance reads when most of three frames read (the camera turned by
``JITTER`` between them, each frame with its own noise). Distances grow by ``GROWTH``
from close up until two in a row fail, then the search bisects to ``TOLERANCE`` after
the last one that read. Near the limit, reads come and go with how the code's cells
fall on pixels, so the result is the edge of mostly reliable reading, give or take a
few centimetres.

Run: ``python -m robots.agent.experiments tag-range`` (about a minute and a half on two
cores) or ``--quick`` (6 cm, marker and QR version 3, at 0 and 60 degrees).
"""

from __future__ import annotations

import argparse
import math
import time
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np

from cloudnav_core.camera import CameraModel
from maps.domain.tagart import qr_centre
from maps.domain.tagpayload import TagPayload, encode_payload
from robots.agent.perception import TagDetector
from robots.agent.sim.camera import Camera
from robots.agent.sim.world import SimTag, World, world_from_grid

SIZES = (0.02, 0.04, 0.06, 0.08)
QR_VERSIONS = (3, 4, 8)
ANGLES = (0.0, 30.0, 45.0, 60.0)
QUICK = ((0.06,), (3,), (0.0, 60.0))
"""Sizes, QR versions and angles of ``--quick``."""

GROWTH = 1.15
TOLERANCE = 0.01
JITTER = (-0.6, 0.0, 0.6)
"""Degrees the camera turns between the frames of one probe: moving the code by a few
pixels changes how its cells fall on pixels, which decides reads near the limit."""
LIMIT = 8.0
"""Metres: farther than any code here can be read, and inside the test wall's length."""

BYTE_CAPACITY_L = {1: 17, 2: 32, 3: 53, 4: 78, 5: 106, 6: 134, 7: 154, 8: 192}
"""Bytes a QR code of each version holds at error correction L in byte mode."""

PAPER_SIZE = 0.06
PAPER = {
    # (size, angle, qr_version or None for the marker): the paper's range in metres.
    (0.06, 0.0, 3): 0.47,
    (0.06, 0.0, 4): 0.43,
    (0.06, 0.0, 8): 0.32,
    (0.06, 0.0, None): 1.128,
    (0.06, 60.0, None): 0.90,
}
"""The paper's figures (Tables 1 and 2) that the issue quotes; its marker was an ARTag."""

_PAYLOAD = TagPayload("http://127.0.0.1:8000", "56037", "boccioni_1", "CorridorA")
_WALL_RESOLUTION = 0.05


@dataclass(frozen=True)
class RangeCase:
    """One measurement: a tag of ``size`` metres seen ``angle`` degrees off its normal;
    ``qr_version`` None measures the marker, a number the QR code of that version."""

    size: float
    angle: float
    qr_version: int | None


@dataclass(frozen=True)
class RangeResult:
    case: RangeCase
    distance: float | None
    """Largest distance (m) at which it was read; None if not even from close up."""
    probes: int
    """Frames rendered and searched."""


def padded_payload(version: int) -> str:
    """The demo payload, padded in its map code so that it needs QR ``version`` at L."""
    text = encode_payload(_PAYLOAD)
    low = BYTE_CAPACITY_L.get(version - 1, 0)
    target = max(len(text), (low + 1 + BYTE_CAPACITY_L[version]) // 2)
    return text + "x" * (target - len(text))


def wall_world(tag: SimTag) -> World:
    """A straight wall along x = 0 (solid for x < 0) facing +x, ``tag`` on it at the
    origin facing +x."""
    half = LIMIT + 1
    cells = round(2 * half / _WALL_RESOLUTION)
    grid = np.zeros((cells, cells), np.int8)
    wall_columns = round(0.5 / _WALL_RESOLUTION)
    grid[:, :wall_columns] = 100
    return world_from_grid(grid, (-0.5, -half), _WALL_RESOLUTION, tags=(tag,))


class _Probe:
    """Renders and reads one case at a given distance."""

    def __init__(self, case: RangeCase, seed: int) -> None:
        model = CameraModel()
        version = case.qr_version or 3
        payload = padded_payload(version)
        self.tag = SimTag(
            0, 0.0, 0.0, 0.0, payload, case.size, model.mount_height, qr_version=version
        )
        self.case, self.model = case, model
        self.camera = Camera(wall_world(self.tag), model, seed=seed)
        self.count = 0

    def reads(self, distance: float) -> bool:
        """Whether the code under test is read from ``distance`` metres in most of a few
        frames, the camera turned slightly between them."""
        votes = sum(self._reads_once(distance, turn) for turn in JITTER)
        return 2 * votes > len(JITTER)

    def _reads_once(self, distance: float, turn: float) -> bool:
        self.count += 1
        x, y, yaw = self._pose(distance)
        image = self.camera.render((x, y, yaw + math.radians(turn)))
        detector = TagDetector(
            read_qr=self.case.qr_version is not None, default_size=self.case.size
        )
        found = [d for d in detector.detect(image) if d.marker_id == self.tag.marker_id]
        if self.case.qr_version is None:
            return bool(found)
        return any(d.qr_text == self.tag.payload for d in found)

    def _pose(self, distance: float) -> tuple[float, float, float]:
        """Robot pose whose camera is ``distance`` from the code's centre, looking at it."""
        tag, angle = self.tag, math.radians(self.case.angle)
        aim = (tag.x, tag.y) if self.case.qr_version is None else qr_centre(0, 0, 0, tag.size)
        eye = (aim[0] + distance * math.cos(angle), aim[1] + distance * math.sin(angle))
        yaw = angle + math.pi
        mount = self.model.mount_x
        return eye[0] - mount * math.cos(yaw), eye[1] - mount * math.sin(yaw), yaw


def max_range(case: RangeCase, seed: int = 0) -> RangeResult:
    """Largest distance at which ``case``'s code is read (see the module's search)."""
    probe = _Probe(case, seed)
    distance = max(0.1, 3 * case.size)  # the whole face in view
    near: float | None = None
    misses = 0
    while distance <= LIMIT and misses < 2:
        if probe.reads(distance):
            near, misses = distance, 0
        else:
            misses += 1
        distance *= GROWTH
    if near is None:
        return RangeResult(case, None, probe.count)
    far = near * GROWTH
    while far - near > TOLERANCE and far <= LIMIT:
        middle = (near + far) / 2
        near, far = (middle, far) if probe.reads(middle) else (near, middle)
    return RangeResult(case, round(near, 3), probe.count)


def cases(
    sizes: Iterable[float], versions: Sequence[int], angles: Sequence[float]
) -> list[RangeCase]:
    """The marker and every QR version, for each size and angle."""
    kinds: list[int | None] = [None, *versions]
    return [RangeCase(s, a, k) for s in sizes for a in angles for k in kinds]


def run(
    sizes: Iterable[float] = SIZES,
    versions: Sequence[int] = QR_VERSIONS,
    angles: Sequence[float] = ANGLES,
) -> list[RangeResult]:
    """Every case's range, each with its own seeded camera."""
    return [max_range(case, seed) for seed, case in enumerate(cases(sizes, versions, angles))]


# --- report ----------------------------------------------------------------------------


def format_tables(results: Sequence[RangeResult]) -> str:
    """Table 1 (range by size, head-on) and Table 2 (range by angle, 6 cm, or the only
    size measured), each cell ``measured (paper)`` where the paper gives a figure."""
    by_case = {r.case: r.distance for r in results}
    sizes = sorted({c.size for c in by_case})
    angles = sorted({c.angle for c in by_case})
    kinds = sorted({c.qr_version for c in by_case}, key=lambda k: -1 if k is None else k)
    header = ["", *(_kind_name(k) for k in kinds)]
    first = [[f"{s * 100:g} cm", *(_cell(by_case, s, 0.0, k) for k in kinds)] for s in sizes]
    size = PAPER_SIZE if PAPER_SIZE in sizes else sizes[0]
    second = [[f"{a:g} deg", *(_cell(by_case, size, a, k) for k in kinds)] for a in angles]
    return "\n".join(
        [
            "Table 1: largest reading distance (m) head-on, by tag size; (paper) where given",
            _grid([header, *first]),
            "",
            f"Table 2: largest reading distance (m) of the {size * 100:g} cm tag, by view angle",
            _grid([header, *second]),
        ]
    )


def _kind_name(kind: int | None) -> str:
    return "marker" if kind is None else f"QR v{kind}"


def _cell(
    by_case: dict[RangeCase, float | None], size: float, angle: float, kind: int | None
) -> str:
    case = RangeCase(size, angle, kind)
    if case not in by_case:
        return ""
    measured = by_case[case]
    text = "-" if measured is None else f"{measured:.2f}"
    paper = PAPER.get((size, angle, kind))
    return text if paper is None else f"{text} ({paper:.2f})"


def _grid(rows: list[list[str]]) -> str:
    widths = [max(len(row[i]) for row in rows) for i in range(len(rows[0]))]
    return "\n".join(
        "  ".join(cell.rjust(w) for cell, w in zip(row, widths, strict=True)) for row in rows
    )


def main(argv: Sequence[str] | None = None) -> int:
    """Command line: print both tables and how long the run took."""
    parser = argparse.ArgumentParser(prog="tag-range", description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="6 cm, marker and QR v3, 0 and 60 deg")
    options = parser.parse_args(argv)
    started = time.perf_counter()
    results = run(*QUICK) if options.quick else run()
    print(format_tables(results))
    probes = sum(r.probes for r in results)
    print(
        f"\n{len(results)} cases, {probes} rendered frames, {time.perf_counter() - started:.1f} s"
    )
    return 0
