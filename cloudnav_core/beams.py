"""The one traversal of an occupancy grid by straight beams: which cells a beam passes
through, exactly, and where along it each is entered, for many beams from one point at
once (the simulator's laser and camera, SLAM's and map upkeep's free space).

A beam is traversed by the cell boundaries it crosses, in the manner of Amanatides and
Woo's grid walk but vectorised over beams and boundaries: from its start cell, the
``k``-th vertical boundary ahead of it takes it into the next column, the ``k``-th
horizontal one into the next row, and each crossing's parameter is exact. From these,
``first_solid`` finds the first solid cell each beam enters (looking a chunk of
boundaries at a time, so its cost follows the distance to the walls) and ``traverse``
lists every cell each beam passes through up to its length, with where it enters and
leaves each (``Traversal.ordered``: in order along each beam).

Positions and lengths here are in cells of the grid (``grid_point``): x along columns, y
along rows, cell ``(row, col)`` covering ``col..col + 1`` by ``row..row + 1``; a beam's
parameter ``t`` is the distance it has travelled, in cells.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from cloudnav_core.grid import BOUNDARY_NUDGE, Indices, Mask, cells_inside, contains
from cloudnav_core.se2 import Floats, Point

CHUNK = 48
"""Boundaries per axis ``first_solid`` tests per beam in one pass; most indoor beams end
in the first."""


@dataclass(frozen=True)
class Beams:
    """Beams from grid point ``(gx, gy)`` (in cells) along unit directions ``(dx, dy)``."""

    gx: float
    gy: float
    dx: Floats
    dy: Floats

    @classmethod
    def towards(cls, gx: float, gy: float, angles: npt.ArrayLike) -> Beams:
        """Beams from grid point ``(gx, gy)`` at ``angles`` (radians, from the x axis)."""
        headings = np.asarray(angles, np.float64)
        return cls(gx, gy, np.cos(headings), np.sin(headings))

    @property
    def start(self) -> tuple[int, int]:
        """``(row, col)`` of the cell every beam starts in."""
        return math.floor(self.gy), math.floor(self.gx)

    def __len__(self) -> int:
        return int(self.dx.size)

    def picked(self, which: Indices) -> Beams:
        """The beams at indices ``which``."""
        return Beams(self.gx, self.gy, self.dx[which], self.dy[which])

    def entries(self, ks: Floats) -> Entries:
        """The cells the beams enter across their ``ks``-th vertical boundaries (columns
        ``0..len(ks)``) and ``ks``-th horizontal ones (the columns after), with the
        parameter of each crossing (``inf`` for a beam parallel to those boundaries)."""
        t_x, col_x, row_x, side_row_x = _crossings(self.gx, self.gy, self.dx, self.dy, ks)
        t_y, row_y, col_y, side_col_y = _crossings(self.gy, self.gx, self.dy, self.dx, ks)
        return Entries(
            np.concatenate((t_x, t_y), axis=1),
            np.concatenate((row_x, row_y), axis=1),
            np.concatenate((col_x, col_y), axis=1),
            np.concatenate((side_row_x, row_y), axis=1),
            np.concatenate((col_x, side_col_y), axis=1),
        )


def grid_point(point: Point, origin: Sequence[float], resolution: float) -> tuple[float, float]:
    """``point`` (map frame, metres) in cells of the grid at ``origin``: ``(gx, gy)``."""
    return (point[0] - origin[0]) / resolution, (point[1] - origin[1]) / resolution


@dataclass(frozen=True)
class Entries:
    """Crossings of cell boundaries, one row per beam: the parameter ``t`` of each and the
    ``rows``, ``cols`` of the cell it enters (floats; meaningless where ``t`` is inf).

    A crossing through a cell corner (within ``BOUNDARY_NUDGE``) enters the diagonal cell,
    on both axes whatever the rounding, and touches the cell beside it at the corner:
    ``side_rows``, ``side_cols`` (the entered cell itself where no corner is near).
    """

    t: Floats
    rows: Floats
    cols: Floats
    side_rows: Floats
    side_cols: Floats


def _crossings(
    g_along: float, g_other: float, d_along: Floats, d_other: Floats, ks: Floats
) -> tuple[Floats, Floats, Floats, Floats]:
    """For the ``ks``-th boundaries perpendicular to one axis: each crossing's parameter,
    the index along that axis of the cell entered, its index along the other, and that
    index a hair before the crossing (the cell touched at a corner, if any).

    From cell ``floor(g)`` a beam moving up the axis crosses boundary ``floor(g) + k``
    into the cell of that index; moving down, ``floor(g) - k + 1`` into the cell below.
    The cell entered is the one holding the point ``BOUNDARY_NUDGE`` cells past the
    crossing.
    """
    backward = (d_along <= 0)[:, None]
    boundary = math.floor(g_along) + np.where(backward, 1.0 - ks, ks)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (boundary - g_along) / d_along[:, None]
    t[d_along == 0] = np.inf  # parallel to these boundaries: its other coordinates are inf
    entered = boundary - backward
    other = g_other + t * d_other[:, None]
    nudge = BOUNDARY_NUDGE * d_other[:, None]
    return t, entered, np.floor(other + nudge), np.floor(other - nudge)


# --- the first solid cell -----------------------------------------------------------------


@dataclass(frozen=True)
class Hits:
    """The first solid cell each beam enters (or touches at a corner): its parameter ``t``
    (``inf`` for none within reach), its ``(row, col)`` (meaningless where ``t`` is inf),
    and ``across_x`` True where the beam entered it across a vertical boundary (a cell
    side perpendicular to x)."""

    t: Floats
    cells: Indices
    across_x: Mask


def first_solid(solid: Mask, beams: Beams, reach: float) -> Hits:
    """The first cell of ``solid`` (cells off the grid are not) each beam enters, or
    touches passing through a corner, within ``reach`` cells. A beam starting in a solid
    cell hits it at ``t`` 0.

    Boundaries are tested ``CHUNK`` per axis at a time; only beams still unresolved go
    on to the next chunk, so the cost follows the distance to the walls, not ``reach``.
    """
    count = len(beams)
    hits = Hits(np.full(count, np.inf), np.zeros((count, 2), np.intp), np.zeros(count, bool))
    if contains(solid.shape, beams.start) and solid[beams.start]:
        hits.t[:], hits.cells[:] = 0.0, beams.start
        return hits
    pending = np.arange(count)
    for start in range(1, math.ceil(reach) + 2, CHUNK):
        ks = np.arange(start, start + CHUNK, dtype=np.float64)
        entries = beams.picked(pending).entries(ks)
        _record(hits, pending, solid, entries)
        # A hit counts once no untested boundary on either axis can come before it.
        looked = np.minimum(entries.t[:, ks.size - 1], entries.t[:, -1])
        pending = pending[hits.t[pending] > looked]
        if pending.size == 0:
            break
    hits.t[hits.t > reach] = np.inf
    return hits


def _record(hits: Hits, beams: Indices, solid: Mask, entries: Entries) -> None:
    """Keep in ``hits``, for ``beams`` (the rows of ``entries``), the first solid cell
    among ``entries`` where it comes before the one found so far."""
    t, side = _blocked(solid, entries)
    first = np.argmin(t, axis=1)
    at = np.arange(beams.size), first
    found = t[at] < hits.t[beams]
    rows = np.where(side[at], entries.side_rows[at], entries.rows[at])
    cols = np.where(side[at], entries.side_cols[at], entries.cols[at])
    hits.t[beams[found]] = t[at][found]
    hits.cells[beams[found]] = np.column_stack((rows, cols))[found]
    hits.across_x[beams[found]] = first[found] < t.shape[1] // 2


def _blocked(solid: Mask, entries: Entries) -> tuple[Floats, Mask]:
    """Each crossing's parameter where it enters or touches a solid cell (else inf), and
    whether that is the cell it touches at a corner (``side_rows``, ``side_cols``): a beam
    through a corner beside a solid cell is stopped by it, so no beam slips between two
    solid cells that meet at a corner."""
    blocked = solid_at(solid, entries.rows, entries.cols)
    corner = (entries.side_rows != entries.rows) | (entries.side_cols != entries.cols)
    side = np.zeros_like(corner)
    side[corner] = solid_at(solid, entries.side_rows[corner], entries.side_cols[corner])
    return np.where(blocked | side, entries.t, np.inf), side


def solid_at(solid: Mask, rows: npt.NDArray[Any], cols: npt.NDArray[Any]) -> Mask:
    """Whether the cells at (possibly off-grid, possibly non-finite) indices are solid."""
    on_grid = cells_inside(solid.shape, rows, cols)
    with np.errstate(invalid="ignore"):
        flat = np.where(on_grid, rows * solid.shape[1] + cols, 0).astype(np.intp)
    found: Mask = np.ravel(solid)[flat] & on_grid
    return found


# --- every cell passed through ------------------------------------------------------------


@dataclass(frozen=True)
class Traversal:
    """Every cell each beam passed through, one entry per (beam, cell), grouped by beam
    (``ordered`` sorts each beam's along it): the beam's index, the cell's ``rows`` and
    ``cols`` (possibly off the grid), and the parameters where the beam ``enters`` it (0
    for its start cell) and ``leaves`` it (at most the beam's length)."""

    beam: Indices
    rows: Indices
    cols: Indices
    enters: Floats
    leaves: Floats

    def ordered(self) -> Traversal:
        """The same entries, each beam's in the order the beam passes its cells."""
        order = np.lexsort((self.enters, self.beam))
        return Traversal(
            self.beam[order], self.rows[order], self.cols[order],
            self.enters[order], self.leaves[order],
        )  # fmt: skip

    def middles(self, beams: Beams) -> tuple[Floats, Floats]:
        """Grid points ``(gx, gy)`` halfway along each beam's stretch in its cell."""
        t = (self.enters + self.leaves) / 2
        return beams.gx + t * beams.dx[self.beam], beams.gy + t * beams.dy[self.beam]


def traverse(beams: Beams, lengths: npt.NDArray[np.floating[Any]]) -> Traversal:
    """The cells each beam passes through from its start up to ``lengths`` cells along it
    (each at least 0): its start cell, then every cell it enters at a parameter up to its
    length, so the cell its end lies in too. A beam through a cell corner goes from one
    cell to the diagonal one; the two beside them, touched at a point, are not listed."""
    reach: Floats = np.asarray(lengths, np.float64)
    count = len(beams)
    ks = np.arange(1, math.ceil(float(reach.max(initial=0.0))) + 2, dtype=np.float64)
    entries = beams.entries(ks)
    start_row, start_col = beams.start
    t = np.concatenate((np.zeros((count, 1)), entries.t), axis=1)
    rows = np.concatenate((np.full((count, 1), start_row, np.float64), entries.rows), axis=1)
    cols = np.concatenate((np.full((count, 1), start_col, np.float64), entries.cols), axis=1)
    kept = t <= reach[:, None]
    # Through a corner both crossings enter the diagonal cell: its horizontal one goes.
    kept[:, 1 + ks.size :] &= entries.side_cols[:, ks.size :] == entries.cols[:, ks.size :]
    beam = np.broadcast_to(np.arange(count)[:, None], t.shape)[kept]
    passed_rows, passed_cols = rows[kept].astype(np.intp), cols[kept].astype(np.intp)
    leaves = _leaves(beams, beam, passed_rows, passed_cols, reach)
    return Traversal(beam, passed_rows, passed_cols, t[kept], leaves)


def _leaves(beams: Beams, beam: Indices, rows: Indices, cols: Indices, lengths: Floats) -> Floats:
    """The parameter where each beam of ``beam`` leaves cell ``(rows, cols)`` through the
    far side it heads for first, or its length if it ends before."""
    dx, dy = beams.dx[beam], beams.dy[beam]
    with np.errstate(divide="ignore", invalid="ignore"):
        out_x = (cols + (dx > 0) - beams.gx) / dx
        out_y = (rows + (dy > 0) - beams.gy) / dy
    out_x[dx == 0] = np.inf
    out_y[dy == 0] = np.inf
    return np.minimum(np.minimum(out_x, out_y), lengths[beam])
