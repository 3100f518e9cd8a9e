"""What the simulated walls look like: procedural panels, stable in the world.

Every wall face is cut into ``PANEL_WIDTH`` metre panels along the wall, each
``wall_height`` tall, drawn at ``TEXEL`` metres per texel. A panel's content (posters
with blocks of print, door frames and leaves, cabinet fronts with handles, tiled dados,
signs, skirting) comes from a generator seeded by the world's ``appearance`` and the
panel's place (which way the face looks, which grid line it stands on, how far along
it), so the same building and seed always look the same, every panel differs, and two
buildings (or seeds) share nothing. A coarser ``STYLE_SPAN`` decides a stretch's
palette and what it tends to hold, so rooms differ in character, not only in detail.

Panels are drawn once, when first seen, and kept (``Wallpaper.panel``); with its two
pre-blurred levels for far walls (so distant print does not alias). Tags stay legible:
the strip of wall around each tag, up to ``TAG_CLEARANCE_HEIGHT``, holds plain wall and
skirting only.

Nothing here imports Django; the simulator's camera samples the panels per column.
"""

from __future__ import annotations

import math
import zlib
from collections.abc import Callable, Iterable
from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

Panel = NDArray[np.uint8]

TEXEL = 0.01
"""Metres per texel of a panel, along the wall and up it."""
PANEL_WIDTH = 1.0
"""Metres of wall per panel."""
STYLE_SPAN = 4.0
"""Metres of wall sharing one style (palette and mix of things on the wall)."""
SKIRTING = 0.1
"""Metres: the darker band at the foot of each wall."""
TAG_CLEARANCE = 0.3
"""Metres either side of a tag's centre (along its wall) kept plain."""
TAG_CLEARANCE_HEIGHT = 0.75
"""Metres: how high the plain strip around a tag reaches."""
FAR_LEVELS = (4.0, 8.0)
"""Metres beyond which the camera samples the first and the second blurred level."""
_BLUR = (1.2, 2.5)
"""Gaussian sigma, in texels, of the two blurred levels."""

EAST, WEST, NORTH, SOUTH = 0, 1, 2, 3
"""Which way a wall face looks (its outward normal)."""

_Drawer = Callable[[Panel, np.random.Generator, "_Style"], None]


@dataclass(frozen=True)
class FacePlace:
    """A wall face: ``facing`` (``EAST`` ...) and ``line``, the grid line it stands on."""

    facing: int
    line: int


class Wallpaper:
    """The panels of one world: ``appearance`` seeds them, ``tags`` (per face, the
    positions along the wall of the tags on it) keep their surroundings plain."""

    def __init__(
        self, appearance: int, wall_height: float, tags: dict[FacePlace, list[float]]
    ) -> None:
        self.appearance = appearance
        self.rows = max(1, math.ceil(wall_height / TEXEL))
        self.columns = round(PANEL_WIDTH / TEXEL)
        self.tags = tags
        self._panels: dict[tuple[int, int, int], tuple[Panel, Panel, Panel]] = {}

    def panel(self, facing: int, line: int, index: int, level: int = 0) -> Panel:
        """Texels of panel ``index`` (along the wall) of a face, row 0 at the floor, at
        blur ``level`` (0 sharp, 1 and 2 for far walls)."""
        key = (facing, line, index)
        levels = self._panels.get(key)
        if levels is None:
            levels = self._panels[key] = self._levels(facing, line, index)
        return levels[level]

    def _levels(self, facing: int, line: int, index: int) -> tuple[Panel, Panel, Panel]:
        sharp = self._draw(facing, line, index)
        near, far = (np.asarray(cv2.GaussianBlur(sharp, (0, 0), s), np.uint8) for s in _BLUR)
        return sharp, near, far

    def _draw(self, facing: int, line: int, index: int) -> Panel:
        style = _Style.of(self._rng(facing, line, math.floor(index * PANEL_WIDTH / STYLE_SPAN)))
        rng = self._rng(facing, line, index, 1)
        canvas = np.full((self.rows, self.columns), style.wall, np.uint8)  # row 0: the top
        _texture(canvas, rng, style.grain)
        for draw in style.pick(rng):
            draw(canvas, rng, style)
        _speckle(canvas, rng, style)
        plain = np.full_like(canvas, style.wall)
        _texture(plain, self._rng(facing, line, index, 2), style.grain)
        self._clear_tags(canvas, plain, FacePlace(facing, line), index)
        _skirting(canvas)
        return np.ascontiguousarray(canvas[::-1])

    def _clear_tags(self, canvas: Panel, plain: Panel, face: FacePlace, index: int) -> None:
        """Plain wall around each tag on this panel's stretch of ``face``."""
        start = index * PANEL_WIDTH
        top = self.rows - round(TAG_CLEARANCE_HEIGHT / TEXEL)
        for along in self.tags.get(face, ()):
            c0 = max(0, round((along - TAG_CLEARANCE - start) / TEXEL))
            c1 = min(self.columns, round((along + TAG_CLEARANCE - start) / TEXEL))
            if c1 > c0:
                canvas[max(top, 0) :, c0:c1] = plain[max(top, 0) :, c0:c1]

    def _rng(self, *place: int) -> np.random.Generator:
        words = [self.appearance & 0xFFFFFFFF, *(p & 0xFFFFFFFF for p in place)]
        return np.random.default_rng(words)


def appearance_of(building_code: str, seed: int) -> int:
    """The appearance number of a building's walls for ``seed`` (stable across runs)."""
    return zlib.crc32(f"{building_code}:{seed}".encode())


def face_of_tag(
    x: float, y: float, yaw: float, origin: tuple[float, float], resolution: float
) -> tuple[FacePlace, float]:
    """The face a tag at ``(x, y)`` facing ``yaw`` hangs on, and its place along it."""
    c, s = math.cos(yaw), math.sin(yaw)
    if abs(c) >= abs(s):
        line = round((x - origin[0]) / resolution)
        return FacePlace(EAST if c > 0 else WEST, line), y
    line = round((y - origin[1]) / resolution)
    return FacePlace(NORTH if s > 0 else SOUTH, line), x


def tags_by_face(
    tags: Iterable[tuple[float, float, float]], origin: tuple[float, float], resolution: float
) -> dict[FacePlace, list[float]]:
    """Tag places ``(x, y, yaw)`` grouped by the face each hangs on."""
    found: dict[FacePlace, list[float]] = {}
    for x, y, yaw in tags:
        face, along = face_of_tag(x, y, yaw, origin, resolution)
        found.setdefault(face, []).append(along)
    return found


# --- styles ------------------------------------------------------------------------------


@dataclass(frozen=True)
class _Style:
    """A stretch of wall's character: its ``wall`` grey, ``ink`` and ``accent`` greys,
    surface ``grain`` and how likely each kind of thing is on a panel."""

    wall: int
    ink: int
    accent: int
    grain: float
    weights: tuple[float, ...]

    @classmethod
    def of(cls, rng: np.random.Generator) -> _Style:
        wall = int(rng.integers(140, 200))
        weights = rng.dirichlet(np.full(len(_THINGS), 0.8))
        return cls(
            wall=wall,
            ink=int(rng.integers(20, 70)),
            accent=int(rng.integers(80, 240)),
            grain=float(rng.uniform(2.0, 7.0)),
            weights=tuple(float(w) for w in weights),
        )

    def pick(self, rng: np.random.Generator) -> list[_Drawer]:
        """Two or three things for a panel, drawn in the order picked."""
        count = int(rng.integers(2, 4))
        chosen = rng.choice(len(_THINGS), size=count, replace=False, p=self.weights)
        return [_THINGS[int(i)] for i in chosen]


def _texture(canvas: Panel, rng: np.random.Generator, grain: float) -> None:
    """Low-contrast blotches (paint, plaster) at a few centimetres' scale."""
    rows, columns = canvas.shape
    coarse = rng.normal(0.0, grain, (rows // 8 + 2, columns // 8 + 2)).astype(np.float32)
    smooth = cv2.resize(coarse, (columns, rows), interpolation=cv2.INTER_CUBIC)
    canvas[:] = np.clip(canvas.astype(np.float32) + smooth, 0, 255).astype(np.uint8)


def _speckle(canvas: Panel, rng: np.random.Generator, style: _Style) -> None:
    """Flecks of a few centimetres over everything (a textured finish, scuffs, pins), so
    a wall seen from close by still has corners to find."""
    rows, columns = canvas.shape
    count = int(style.grain * 25)
    xs, ys = rng.integers(0, columns - 2, count), rng.integers(0, rows - 2, count)
    sizes = rng.integers(1, 4, (count, 2))
    shifts = rng.choice((-1, 1), count) * rng.integers(25, 60, count)
    for x, y, (w, h), shift in zip(xs, ys, sizes, shifts, strict=True):
        patch = canvas[y : y + h, x : x + w].astype(np.int16) + shift
        canvas[y : y + h, x : x + w] = np.clip(patch, 0, 255).astype(np.uint8)


def _skirting(canvas: Panel) -> None:
    band = round(SKIRTING / TEXEL)
    canvas[-band:] = (canvas[-band:].astype(np.float32) * 0.55).astype(np.uint8)
    canvas[-band] = canvas[-band] // 2  # its top edge


def _rows_up(canvas: Panel, metres: float) -> int:
    """Canvas row (row 0 at the top) at ``metres`` above the floor."""
    return int(np.clip(canvas.shape[0] - round(metres / TEXEL), 0, canvas.shape[0] - 1))


def _poster(canvas: Panel, rng: np.random.Generator, style: _Style) -> None:
    """A framed poster or notice: border, blocks of colour, lines of print, a disc."""
    width, height = int(rng.integers(35, 85)), int(rng.integers(45, 95))
    x0 = int(rng.integers(2, canvas.shape[1] - width - 1))
    y0 = _rows_up(canvas, float(rng.uniform(0.55, 1.7))) - height // 2
    y0 = int(np.clip(y0, 2, canvas.shape[0] - height - 2))
    x1, y1 = x0 + width, y0 + height
    paper = int(rng.integers(185, 250))
    cv2.rectangle(canvas, (x0, y0), (x1, y1), paper, -1)
    cv2.rectangle(canvas, (x0, y0), (x1, y1), style.ink, 2)
    for _ in range(int(rng.integers(1, 4))):  # pictures
        bw, bh = int(rng.integers(8, width // 2 + 8)), int(rng.integers(6, height // 3 + 6))
        bx, by = (
            x0 + int(rng.integers(3, max(4, width - bw - 2))),
            y0 + int(rng.integers(3, max(4, height - bh - 2))),
        )
        cv2.rectangle(
            canvas,
            (bx, by),
            (min(bx + bw, x1 - 3), min(by + bh, y1 - 3)),
            int(rng.integers(30, 220)),
            -1,
        )
    _print_lines(canvas, rng, (x0 + 4, y0 + height // 2, x1 - 4, y1 - 4), style.ink)
    if rng.random() < 0.5:
        centre = (x0 + int(rng.integers(8, width - 7)), y0 + int(rng.integers(8, height - 7)))
        cv2.circle(canvas, centre, int(rng.integers(3, 8)), style.accent, -1)


def _print_lines(
    canvas: Panel, rng: np.random.Generator, box: tuple[int, int, int, int], ink: int
) -> None:
    """Lines of 'words': short dark bars with gaps, as print looks from a metre away."""
    x0, y0, x1, y1 = box
    y = y0
    while y + 2 < y1:
        x = x0
        while x < x1 - 3:
            word = int(rng.integers(3, 12))
            cv2.rectangle(canvas, (x, y), (min(x + word, x1), y + 1), ink, -1)
            x += word + int(rng.integers(2, 4))
        y += int(rng.integers(4, 7))


def _door(canvas: Panel, rng: np.random.Generator, style: _Style) -> None:
    """A closed door: frame, leaf of another grey, panels, a handle and a plate."""
    width = int(rng.integers(70, 92))
    x0 = int(rng.integers(1, canvas.shape[1] - width))
    top = _rows_up(canvas, 2.05)
    bottom = canvas.shape[0] - 1
    leaf = int(rng.integers(60, 230))
    cv2.rectangle(canvas, (x0, top), (x0 + width, bottom), style.ink, -1)
    cv2.rectangle(canvas, (x0 + 4, top + 4), (x0 + width - 4, bottom), leaf, -1)
    for a, b in ((0.08, 0.45), (0.55, 0.92)):
        py0, py1 = top + int(a * (bottom - top)), top + int(b * (bottom - top))
        shade = int(np.clip(leaf + rng.integers(-45, 45), 0, 255))
        cv2.rectangle(canvas, (x0 + 12, py0), (x0 + width - 12, py1), shade, 2)
    handle_y = _rows_up(canvas, 1.0)
    hx = x0 + width - 14 if rng.random() < 0.5 else x0 + 8
    cv2.rectangle(canvas, (hx, handle_y - 2), (hx + 7, handle_y + 2), 255 - leaf // 2, -1)
    plate_y = _rows_up(canvas, 1.6)
    cv2.rectangle(canvas, (x0 + 25, plate_y), (x0 + width - 25, plate_y + 9), 240, -1)
    _print_lines(canvas, rng, (x0 + 27, plate_y + 2, x0 + width - 27, plate_y + 8), style.ink)


def _cabinet(canvas: Panel, rng: np.random.Generator, style: _Style) -> None:
    """A low cabinet or shelf front against the wall: doors or drawers with handles."""
    width, height = int(rng.integers(50, 96)), int(rng.integers(55, 105))
    x0 = int(rng.integers(1, canvas.shape[1] - width))
    bottom = _rows_up(canvas, SKIRTING + 0.02)
    top = bottom - height
    body = int(rng.integers(40, 220))
    cv2.rectangle(canvas, (x0, top), (x0 + width, bottom), body, -1)
    cv2.rectangle(canvas, (x0, top), (x0 + width, bottom), style.ink, 1)
    drawers = int(rng.integers(2, 5))
    for i in range(drawers):
        y = top + (i * height) // drawers
        cv2.line(canvas, (x0, y), (x0 + width, y), style.ink, 1)
        hy = y + height // (2 * drawers)
        cv2.rectangle(
            canvas, (x0 + width // 2 - 6, hy - 1), (x0 + width // 2 + 6, hy + 1), 255 - body, -1
        )


def _dado(canvas: Panel, rng: np.random.Generator, style: _Style) -> None:
    """Tiles below a rail: a grid of slightly varied tiles, grout lines between them."""
    rail = _rows_up(canvas, float(rng.uniform(0.6, 1.2)))
    size = int(rng.integers(8, 20))
    floor = canvas.shape[0]
    for y in range(rail, floor, size):
        for x in range(int(rng.integers(0, size)) - size, canvas.shape[1], size):
            tone = int(np.clip(style.accent + rng.integers(-25, 26), 0, 255))
            cv2.rectangle(canvas, (x + 1, y + 1), (x + size - 1, y + size - 1), tone, -1)
    cv2.rectangle(canvas, (0, rail - 3), (canvas.shape[1], rail), style.ink, -1)


def _sign(canvas: Panel, rng: np.random.Generator, style: _Style) -> None:
    """A small sign or switch plate: a dark or light plate with a symbol."""
    width, height = int(rng.integers(14, 40)), int(rng.integers(10, 24))
    x0 = int(rng.integers(2, canvas.shape[1] - width - 2))
    y0 = _rows_up(canvas, float(rng.uniform(0.3, 1.5)))
    y0 = int(np.clip(y0, 2, canvas.shape[0] - height - 2))
    plate = 240 if rng.random() < 0.5 else style.ink
    cv2.rectangle(canvas, (x0, y0), (x0 + width, y0 + height), plate, -1)
    symbol = 255 - plate
    kind = int(rng.integers(3))
    centre = (x0 + width // 2, y0 + height // 2)
    if kind == 0:
        cv2.circle(canvas, centre, max(2, height // 3), symbol, 2)
    elif kind == 1:
        pts = np.array(
            [[x0 + 3, y0 + height - 3], [centre[0], y0 + 3], [x0 + width - 3, y0 + height - 3]]
        )
        cv2.fillPoly(canvas, [pts.astype(np.int32)], symbol)
    else:
        cv2.line(canvas, (x0 + 3, centre[1]), (x0 + width - 3, centre[1]), symbol, 2)
        cv2.line(canvas, (x0 + width - 8, centre[1] - 4), (x0 + width - 3, centre[1]), symbol, 2)


def _stripes(canvas: Panel, rng: np.random.Generator, style: _Style) -> None:
    """A band of stripes or a chequer (a patterned wall covering or a noticeboard)."""
    y0 = _rows_up(canvas, float(rng.uniform(0.4, 1.6)))
    height = int(rng.integers(15, 45))
    width = int(rng.integers(6, 16))
    checker = rng.random() < 0.5
    for i, x in enumerate(range(0, canvas.shape[1], width)):
        if checker:
            for j, y in enumerate(range(y0, min(y0 + height, canvas.shape[0]), width)):
                if (i + j) % 2 == 0:
                    cv2.rectangle(canvas, (x, y), (x + width - 1, y + width - 1), style.accent, -1)
        elif i % 2 == 0:
            cv2.rectangle(canvas, (x, y0), (x + width - 1, y0 + height), style.accent, -1)


_THINGS = (_poster, _door, _cabinet, _dado, _sign, _stripes)
