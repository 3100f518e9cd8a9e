"""The 3D maps of a visual session: a coloured point cloud (binary PLY) and an OctoMap.

Each keyframe keeps its own coloured cloud in the robot's frame (``KeyframeCloud``): every
``STRIDE``-th pixel of its registered depth lifted to 3D by the camera model every visual
module uses (``keyframes.back_project``: ``Intrinsics`` and ``Mount``), coloured by the
image, and thinned to one point per ``VOXEL`` cube. Kept in the robot's frame, a cloud
never changes when a loop closure moves its keyframe: the map's cloud is each keyframe's
cloud placed at its optimised pose (``placed``), thinned again to one point per voxel
across keyframes (``map_cloud``), so it stays bounded by the mapped surface's area
rather than the time spent mapping, and is cut at ``MAX_POINTS`` all the same.

The OctoMap (``octomap_bytes``, through ``pyoctomap``, the maintained binding of the
OctoMap library) inserts each keyframe's cloud as one scan ray-cast from the camera's
optical centre: the voxels its rays cross are free, those they end in occupied, as
``octomap_server`` builds one from a depth camera. Its ``.bt`` is what ``octovis`` and
``octomap_server`` read.

Nothing here imports Django.
"""

from __future__ import annotations

import io
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import plyfile
import pyoctomap
from numpy.typing import NDArray

from cloudnav_core.camera import Intrinsics, Mount
from cloudnav_core.se2 import Pose
from maps.domain.keyframes import DEPTH_RANGE, Depth, Image, back_project

STRIDE = 4
"""Pixels: every STRIDE-th row and column of a keyframe's depth is lifted (19,200 points
from a 640x480 camera before thinning); a colour image decoded at 1/STRIDE scale
(``cv2.IMREAD_REDUCED_COLOR_4``) gives one colour a point."""
VOXEL = 0.05
"""Metres: a cloud keeps one point (the mean, of mean colour) per cube of this side."""
MAX_POINTS = 400_000
"""Points a map's cloud holds at most (6 MB of PLY): about 1,000 m2 of surface at 5 cm."""
PLY_VERTEX = np.dtype(
    [("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("red", "u1"), ("green", "u1"), ("blue", "u1")]
)
"""A PLY vertex as Open3D, MeshLab and CloudCompare read a coloured point: 15 bytes."""
FEED_KEYFRAMES = 8
"""Keyframes' clouds one answer of the live feed carries at most (about 50 kB each)."""
OCTOMAP_RESOLUTION = 0.05
"""Metres: the OctoMap's finest voxel."""


@dataclass(frozen=True)
class KeyframeCloud:
    """Points (n x 3, metres, float32) and their colours (n x 3, RGB, uint8)."""

    points: NDArray[np.float32]
    colours: NDArray[np.uint8]

    def __len__(self) -> int:
        return len(self.points)

    @classmethod
    def empty(cls) -> KeyframeCloud:
        return cls(np.zeros((0, 3), np.float32), np.zeros((0, 3), np.uint8))


def keyframe_cloud(
    depth: Depth,
    intrinsics: Intrinsics,
    mount: Mount,
    colour: Image | None = None,
    grey: Image | None = None,
    voxel: float = VOXEL,
) -> KeyframeCloud:
    """The coloured cloud of one keyframe in its robot's frame (x forward, y left, z up
    from the floor): readings within ``DEPTH_RANGE``, one point per ``voxel``. ``colour``
    is the image at 1/``STRIDE`` scale (RGB); without it the full-size ``grey`` image
    gives grey points, and without either they are white."""
    rows = np.arange(0, depth.shape[0], STRIDE)
    cols = np.arange(0, depth.shape[1], STRIDE)
    grid_rows, grid_cols = np.meshgrid(rows, cols, indexing="ij")
    z = np.asarray(depth, np.float32)[grid_rows, grid_cols]
    with np.errstate(invalid="ignore"):
        usable = np.isfinite(z) & (z >= DEPTH_RANGE[0]) & (z <= DEPTH_RANGE[1])
    pixels = np.stack([grid_cols[usable], grid_rows[usable]], axis=1).astype(np.float32)
    points = back_project(pixels, z[usable], (0.0, 0.0, 0.0), intrinsics, mount)
    colours = _colours(usable, colour, grey, grid_rows, grid_cols)
    return thinned(KeyframeCloud(points, colours), voxel)


def _colours(
    usable: NDArray[np.bool_],
    colour: Image | None,
    grey: Image | None,
    rows: NDArray[np.intp],
    cols: NDArray[np.intp],
) -> NDArray[np.uint8]:
    if colour is not None:
        small_rows = np.minimum(rows[usable] // STRIDE, colour.shape[0] - 1)
        small_cols = np.minimum(cols[usable] // STRIDE, colour.shape[1] - 1)
        return np.asarray(colour[small_rows, small_cols, :3], np.uint8)
    if grey is not None:
        return np.repeat(np.asarray(grey[rows[usable], cols[usable]], np.uint8)[:, None], 3, 1)
    return np.full((int(usable.sum()), 3), 255, np.uint8)


def thinned(cloud: KeyframeCloud, voxel: float = VOXEL) -> KeyframeCloud:
    """One point per cube of side ``voxel``: the mean of the points in it, of their mean
    colour."""
    if not len(cloud):
        return cloud
    keys = np.floor(cloud.points / voxel).astype(np.int64)
    keys -= keys.min(axis=0)
    spans = keys.max(axis=0) + 1  # one integer per cube: np.unique on rows is 10 times slower
    flat = (keys[:, 0] * spans[1] + keys[:, 1]) * spans[2] + keys[:, 2]
    _, cube, count = np.unique(flat, return_inverse=True, return_counts=True)

    def means(values: NDArray[Any]) -> NDArray[np.float64]:
        sums = [np.bincount(cube, values[:, axis], len(count)) for axis in range(3)]
        return np.stack(sums, axis=1) / count[:, None]

    return KeyframeCloud(
        means(cloud.points).astype(np.float32), np.rint(means(cloud.colours)).astype(np.uint8)
    )


def placed(cloud: KeyframeCloud, pose: Pose) -> KeyframeCloud:
    """``cloud`` (robot frame) in the map's frame, its robot at ``pose``."""
    c, s = math.cos(pose[2]), math.sin(pose[2])
    x, y = cloud.points[:, 0], cloud.points[:, 1]
    moved = np.stack([pose[0] + c * x - s * y, pose[1] + s * x + c * y, cloud.points[:, 2]], 1)
    return KeyframeCloud(moved.astype(np.float32), cloud.colours)


def map_cloud(
    clouds: Sequence[KeyframeCloud],
    poses: Sequence[Pose],
    voxel: float = VOXEL,
    max_points: int = MAX_POINTS,
) -> KeyframeCloud:
    """The keyframes' clouds at their poses, one point per ``voxel`` across them all, at
    most ``max_points`` (evenly taken when there are more)."""
    views = [placed(cloud, pose) for cloud, pose in zip(clouds, poses, strict=True)]
    if not views:
        return KeyframeCloud.empty()
    merged = KeyframeCloud(
        np.concatenate([v.points for v in views]), np.concatenate([v.colours for v in views])
    )
    cloud = thinned(merged, voxel)
    if len(cloud) > max_points:
        kept = np.linspace(0, len(cloud) - 1, max_points).astype(np.intp)
        cloud = KeyframeCloud(cloud.points[kept], cloud.colours[kept])
    return cloud


def ply_bytes(cloud: KeyframeCloud) -> bytes:
    """``cloud`` as a binary little-endian PLY (``x y z`` float, ``red green blue``
    uchar), written by ``plyfile``: what Open3D, MeshLab and CloudCompare read."""
    vertices = np.empty(len(cloud), dtype=PLY_VERTEX)
    for axis, name in enumerate("xyz"):
        vertices[name] = cloud.points[:, axis]
    for channel, name in enumerate(("red", "green", "blue")):
        vertices[name] = cloud.colours[:, channel]
    element = plyfile.PlyElement.describe(vertices, "vertex")
    out = io.BytesIO()
    plyfile.PlyData([element], text=False, byte_order="<").write(out)
    return out.getvalue()


def octomap_bytes(
    clouds: Sequence[KeyframeCloud],
    poses: Sequence[Pose],
    mount: Mount,
    resolution: float = OCTOMAP_RESOLUTION,
) -> bytes:
    """The OctoMap (``.bt``, maximum-likelihood binary) of the keyframes' clouds, each
    inserted as a scan ray-cast from its camera's optical centre."""
    tree = pyoctomap.OcTree(resolution)
    for cloud, pose in zip(clouds, poses, strict=True):
        if not len(cloud):
            continue
        points = placed(cloud, pose).points.astype(np.float64)
        c, s = math.cos(pose[2]), math.sin(pose[2])
        origin = np.array([pose[0] + mount.forward * c, pose[1] + mount.forward * s, mount.height])
        tree.insertPointCloud(points, origin, max_range=DEPTH_RANGE[1], lazy_eval=True)
    tree.updateInnerOccupancy()
    return bytes(tree.writeBinary())  # no file name: the bytes are returned


def feed_bytes(
    clouds: Sequence[KeyframeCloud],
    poses: Sequence[Pose],
    loops: Sequence[tuple[int, int]],
    start: int,
    limit: int = FEED_KEYFRAMES,
) -> bytes:
    """The live 3D view's feed: every keyframe's optimised pose and the loop closures,
    with the clouds (robot frame) of at most ``limit`` keyframes from ``start`` on. The
    page places each cloud at its keyframe's pose, so a loop closure moves what it drew
    without its points being sent again. Little-endian, 4-byte aligned:

    - int32 ``keyframes, start, clouds, loops``;
    - float32 ``x, y, yaw`` of each keyframe; int32 ``i, j`` of each loop;
    - for each cloud: int32 ``n``, float32 ``x, y, z`` of its n points, uint8 ``r, g,
      b`` of each, zero-padded to a multiple of 4 bytes.
    """
    start = max(0, min(start, len(clouds)))
    sent = list(clouds[start : start + limit])
    parts = [
        np.array([len(poses), start, len(sent), len(loops)], "<i4").tobytes(),
        np.asarray(poses, "<f4").reshape(-1, 3).tobytes(),
        np.asarray(loops, "<i4").reshape(-1, 2).tobytes(),
    ]
    for cloud in sent:
        colours = cloud.colours.astype(np.uint8).tobytes()
        parts += [
            np.array([len(cloud)], "<i4").tobytes(),
            cloud.points.astype("<f4").tobytes(),
            colours + bytes(-len(colours) % 4),
        ]
    return b"".join(parts)
