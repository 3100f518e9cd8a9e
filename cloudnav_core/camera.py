"""The robots' camera: a pinhole (no distortion) and where it sits on the robot.

One home for the camera's defaults (the robots' Xtion, 0.05 m ahead of the robot's centre
and 0.25 m above the floor), shared by the server's visual maps (``Intrinsics``,
``Mount``) and the robot's perception (``CameraModel``, both in one).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

Matrix = NDArray[np.float64]


@dataclass(frozen=True)
class Intrinsics:
    """A pinhole camera (no distortion): the robots' Xtion by default."""

    width: int = 640
    height: int = 480
    fx: float = 525.0
    fy: float = 525.0
    cx: float = 319.5
    cy: float = 239.5

    def matrix(self) -> Matrix:
        """The 3x3 intrinsic matrix K."""
        return np.array([[self.fx, 0, self.cx], [0, self.fy, self.cy], [0, 0, 1]], np.float64)


@dataclass(frozen=True)
class Mount:
    """Where the camera sits on the robot: ``forward`` of its centre, ``height`` above
    the floor, looking level along its heading."""

    forward: float = 0.05
    height: float = 0.25


@dataclass(frozen=True)
class CameraModel(Intrinsics):
    """Pinhole calibration (no distortion) and where the camera sits on the robot."""

    mount_x: float = Mount.forward
    mount_height: float = Mount.height

    def base_from_camera(self, point: Sequence[float] | Matrix) -> Matrix:
        """A point (or a stack of points, shape (..., 3)) from the optical to the base frame."""
        p = np.asarray(point, np.float64)
        return np.stack(
            [p[..., 2] + self.mount_x, -p[..., 0], self.mount_height - p[..., 1]], axis=-1
        )

    def base_direction(self, vector: Sequence[float] | Matrix) -> Matrix:
        """A direction from the optical to the base frame (no offset)."""
        v = np.asarray(vector, np.float64)
        return np.stack([v[..., 2], -v[..., 0], -v[..., 1]], axis=-1)
