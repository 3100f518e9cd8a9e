"""Rigid motions of the floor plane, SE(2): poses ``(x, y, yaw)`` and the frames they make.

A pose ``a`` places a child frame in its parent's frame (metres, radians counter-clockwise
from the parent's x axis). ``compose(a, b)`` is ``b``, given in ``a``'s frame, in ``a``'s
parent's; ``inverse(a)`` is the parent seen from ``a``; ``relative(a, b)`` is ``b`` seen
from ``a``. Every yaw these return is wrapped into [-pi, pi).

Single poses are tuples of floats worked with ``math``; ``wrap`` also takes arrays, and
``transform`` and ``transform_each`` move arrays of points (laser returns, beam endpoints
under every particle) with numpy.
"""

from __future__ import annotations

import math
from typing import Any, overload

import numpy as np
from numpy.typing import NDArray

Pose = tuple[float, float, float]
"""``(x, y, yaw)``: metres, metres, radians."""
Point = tuple[float, float]
"""``(x, y)`` in metres."""
Floats = NDArray[np.float64]

_TURN = 2 * math.pi


@overload
def wrap(angle: float) -> float: ...
@overload
def wrap(angle: NDArray[Any]) -> Floats: ...
def wrap(angle: float | NDArray[Any]) -> float | Floats:
    """``angle`` (radians, or an array of them) in [-pi, pi)."""
    return (angle + math.pi) % _TURN - math.pi


def angle_between(first: float, second: float) -> float:
    """Absolute difference of two angles, radians in [0, pi]."""
    return abs(wrap(first - second))


def compose(a: Pose, b: Pose) -> Pose:
    """Pose ``b`` (given in frame ``a``) in ``a``'s parent frame."""
    c, s = math.cos(a[2]), math.sin(a[2])
    return a[0] + c * b[0] - s * b[1], a[1] + s * b[0] + c * b[1], wrap(a[2] + b[2])


def inverse(a: Pose) -> Pose:
    """The pose of the parent frame seen from ``a``."""
    c, s = math.cos(a[2]), math.sin(a[2])
    return -c * a[0] - s * a[1], s * a[0] - c * a[1], wrap(-a[2])


def relative(a: Pose, b: Pose) -> Pose:
    """Pose ``b`` seen from ``a`` (both in one frame): ``compose(inverse(a), b)``, computed
    directly. From two odometry poses it is the motion between them, in the robot frame at
    the first: ``(forward, left, turn)``."""
    dx, dy = b[0] - a[0], b[1] - a[1]
    c, s = math.cos(a[2]), math.sin(a[2])
    return c * dx + s * dy, -s * dx + c * dy, wrap(b[2] - a[2])


def ahead(pose: Pose, distance: float) -> Point:
    """The point ``distance`` metres in front of ``pose``, along its heading."""
    x, y, yaw = pose
    return x + distance * math.cos(yaw), y + distance * math.sin(yaw)


def transform(pose: Pose, points: Floats) -> Floats:
    """``points`` (shape (n, 2)) given in ``pose``'s frame, in its parent's."""
    c, s = math.cos(pose[2]), math.sin(pose[2])
    x, y = points[:, 0], points[:, 1]
    return np.stack([pose[0] + c * x - s * y, pose[1] + s * x + c * y], 1)


def transform_each(poses: Floats, x: Floats | float, y: Floats | float) -> tuple[Floats, Floats]:
    """The points ``(x, y)`` (arrays of one shape (m,), or one point) given in the frame of
    each of ``poses`` (shape (n, 3)), in the parent frame: x and y of shape (n, m)."""
    c, s = np.cos(poses[:, 2:3]), np.sin(poses[:, 2:3])
    return poses[:, 0:1] + c * x - s * y, poses[:, 1:2] + s * x + c * y


def aligning(source: Floats, target: Floats) -> Pose:
    """The rigid motion (no scale) that best carries ``source`` points (shape (n, 2)) onto
    ``target`` (the same points as another frame has them), in least squares: Umeyama's
    closed form (1991) in the plane. Raises ValueError for fewer than 2 points."""
    if len(source) < 2 or source.shape != target.shape:
        raise ValueError("aligning needs 2 or more point pairs of one shape")
    source_mean, target_mean = source.mean(axis=0), target.mean(axis=0)
    covariance = (target - target_mean).T @ (source - source_mean)
    u, _, vt = np.linalg.svd(covariance)
    flip = np.diag([1.0, float(np.sign(np.linalg.det(u @ vt)) or 1.0)])
    rotation = u @ flip @ vt
    x, y = target_mean - rotation @ source_mean
    return float(x), float(y), math.atan2(float(rotation[1, 0]), float(rotation[0, 0]))
