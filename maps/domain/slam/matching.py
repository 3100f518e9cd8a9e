"""Correlative scan matching: the likelihood field of the map near the robot (``Field``,
``likelihood_field``) and the search over poses that places a scan best on it
(``search``).

The scan is matched against a *likelihood field* of the map near the robot (the points of
recent and nearby keyframes, blurred by a Gaussian of the distance to the nearest one), by
an exhaustive search over a small window of positions and headings, coarse then fine, with
bilinear look-ups (the real-time correlative scan matching of Olson, 2009, as Cartographer
and Karto use it). No well-kept PyPI library does 2D scan matching (BreezySLAM's last
release is from 2018; KISS-ICP and small_gicp are 3D point cloud registration), so it is
here, in numpy.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from cloudnav_core.grid import cells_of
from cloudnav_core.se2 import Floats, Pose, wrap

from .params import SlamParams


@dataclass
class Field:
    """A field over the plane scored by ``search`` (higher fits better): ``values[row,
    col]`` at cell centres (a likelihood in [0, 1], or minus a distance), cell (0, 0)'s
    corner at ``origin``."""

    values: Floats
    origin: tuple[float, float]
    resolution: float

    def score(self, points: Floats, poses: Floats) -> Floats:
        """Mean likelihood of ``points`` (robot frame, (n, 2)) placed at each of ``poses``
        ((m, 3)); returns (m,)."""
        cos, sin = np.cos(poses[:, 2])[:, None], np.sin(poses[:, 2])[:, None]
        x = poses[:, 0:1] + cos * points[:, 0] - sin * points[:, 1]
        y = poses[:, 1:2] + sin * points[:, 0] + cos * points[:, 1]
        col = (x - self.origin[0]) / self.resolution - 0.5
        row = (y - self.origin[1]) / self.resolution - 0.5
        scores: Floats = _bilinear(self.values, row, col).mean(axis=1)
        return scores


def _bilinear(values: Floats, row: Floats, col: Floats) -> Floats:
    height, width = values.shape
    r0 = np.clip(np.floor(row).astype(np.intp), 0, height - 2)
    c0 = np.clip(np.floor(col).astype(np.intp), 0, width - 2)
    fr = np.clip(row - r0, 0.0, 1.0)
    fc = np.clip(col - c0, 0.0, 1.0)
    top = values[r0, c0] * (1 - fc) + values[r0, c0 + 1] * fc
    bottom = values[r0 + 1, c0] * (1 - fc) + values[r0 + 1, c0 + 1] * fc
    return top * (1 - fr) + bottom * fr


def search(
    field: Field, points: Floats, guess: Pose, window_xy: float, window_yaw: float, step: float
) -> tuple[Pose, float]:
    """The pose near ``guess`` where ``points`` score best on ``field``: searched over
    ``+-window_xy`` by ``step`` (and the heading likewise), then refined twice around the
    best by half of the last steps; returns it with its score."""
    yaw_step = max(math.radians(1.0), step * 0.6)
    candidates = _grid_of_poses(guess, window_xy, step, window_yaw, yaw_step)
    best, score = _best(field, points, candidates)
    for _ in range(2):
        step, yaw_step = step / 2, yaw_step / 2
        best, score = _best(field, points, _grid_of_poses(best, step, step, yaw_step, yaw_step))
    return (best[0], best[1], wrap(best[2])), score


def _best(field: Field, points: Floats, candidates: Floats) -> tuple[Pose, float]:
    scores = field.score(points, candidates)
    top = int(np.argmax(scores))
    pose = (float(candidates[top, 0]), float(candidates[top, 1]), float(candidates[top, 2]))
    return pose, float(scores[top])


def _grid_of_poses(
    centre: Pose, span_xy: float, step: float, span_yaw: float, yaw_step: float
) -> Floats:
    offsets = np.arange(-span_xy, span_xy + step / 2, step)
    turns = np.arange(-span_yaw, span_yaw + yaw_step / 2, yaw_step)
    dx, dy, dyaw = np.meshgrid(offsets, offsets, turns, indexing="ij")
    return np.column_stack(
        (centre[0] + dx.ravel(), centre[1] + dy.ravel(), centre[2] + dyaw.ravel())
    )


def likelihood_field(points: Floats, centre: Pose, extent: float, params: SlamParams) -> Field:
    """The likelihood field of map-frame ``points`` within ``extent`` metres of
    ``centre``: exp(-d^2 / 2 sigma^2) of the distance d to the nearest point."""
    from scipy.ndimage import distance_transform_edt

    res = params.resolution
    origin = (
        math.floor((centre[0] - extent) / res) * res,
        math.floor((centre[1] - extent) / res) * res,
    )
    size = math.ceil(2 * extent / res) + 1
    occupied = np.zeros((size, size), dtype=bool)
    rows, cols = cells_of(points[:, 0], points[:, 1], origin, res, nudge=0.0)
    inside = (rows >= 0) & (rows < size) & (cols >= 0) & (cols < size)
    occupied[rows[inside], cols[inside]] = True
    if not occupied.any():
        return Field(np.zeros((size, size)), origin, res)
    distance = distance_transform_edt(~occupied) * res
    return Field(np.exp(-(distance**2) / (2 * params.sigma**2)), origin, res)
