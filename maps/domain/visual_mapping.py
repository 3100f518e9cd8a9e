"""A visual mapping session's map: the tracking core (``visual_slam``) fed with a robot's
camera frames, the obstacle scan of each keyframe's depth for the 2D grid
(``visual_grid``), the coloured cloud of each keyframe for the 3D maps (``visual_cloud``),
the figures the session shows, and the state a stopped session resumes
from (and is published from: its keyframes become the sub-map's relocalisation map).

A frame is refused whole (KeyframeError naming the field, nothing of it kept, the map as
it was) when it comes out of order (a stamp not after the last frame's), when its depth
does not match its image, or when its depth is not finite numbers (``visual_input``).

Nothing here imports Django.
"""

from __future__ import annotations

import io
import math
import weakref
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from cloudnav_core.camera import Intrinsics
from cloudnav_core.se2 import Pose, angle_between
from maps.domain.keyframes import Depth, Image
from maps.domain.keyframes import Keyframe as Features
from maps.domain.slam.occupancy import Grid, LogOddsGrid
from maps.domain.slam.params import SlamParams
from maps.domain.slam.scans import Scan
from maps.domain.visual_cloud import KeyframeCloud, keyframe_cloud
from maps.domain.visual_grid import obstacle_scan
from maps.domain.visual_input import (
    depth_image,
    finite_depth,
    grey_image,
    intrinsics_of,
    quarter_colour_image,
    stamp_of,
)
from maps.domain.visual_slam import Edge, State, VisualSlam
from maps.domain.vocabulary import Vocabulary
from maps.exceptions import KeyframeError

GRID_TOLERANCE = (0.0125, math.radians(0.2))
"""How far (metres, radians) loop closures may move a keyframe before the grid is made
again from all of them: a quarter of a 5 cm cell, and a turn that moves a point 4 m away
by 1.4 cm. Loop closures on a second lap move most keyframes by millimetres, and making
the grid again at every one took most of a lap's processor time."""


@dataclass
class VisualMapStats:
    """What the session did, for its page (the laser mapper's ``MapStats`` of a camera)."""

    frames: int = 0
    tracked: int = 0
    relocalised: int = 0
    lost: int = 0
    restarted: int = 0  # lost frames that started mapping again from odometry's pose
    keyframes: int = 0
    loop_closures: int = 0
    refused: int = 0  # frames of bad input (out of order, depth not matching, ...)


@dataclass(frozen=True)
class Frame:
    """One decoded camera frame: its stamp (seconds), grey image, registered depth
    (metres, NaN for no reading), camera, and the odometry pose of its instant if any."""

    stamp: float
    image: Image
    depth: Depth
    intrinsics: Intrinsics
    odometry: Pose | None = None


def frame_of(
    image: Any, depth: Any, camera_info: Any, odometry: Pose | None, max_pixels: int
) -> Frame:
    """The ``Frame`` of a robot's messages in rosbridge JSON: a ``CompressedImage``, its
    registered depth (compressedDepth or raw ``Image``) and ``CameraInfo`` (None: the
    default camera). Raises KeyframeError naming the message at fault."""
    stamp = stamp_of(image, "image")
    grey = grey_image(image, max_pixels)
    finite_depth(depth)
    metres = depth_image(depth, grey.shape, max_pixels)
    return Frame(stamp, grey, metres, intrinsics_of(camera_info, grey.shape), odometry)


def colour_of(image: Any, max_pixels: int) -> Colour:
    """What ``VisualMapper.add`` asks for a keyframe's colours: ``image`` (the frame's
    ``CompressedImage``) decoded at a quarter of its size, or None when it cannot be
    (its grey pixels colour the cloud then)."""

    def decoded() -> Image | None:
        try:
            return quarter_colour_image(image, max_pixels)
        except KeyframeError:
            return None

    return decoded


Colour = Callable[[], Image | None]
"""A frame's colours (RGB at a quarter of its size), decoded only when asked: only a
keyframe's are (2.4 ms a 640x480 JPEG)."""


class VisualMapper:
    """Builds one map from a stream of ``Frame``s."""

    def __init__(
        self, vocabulary: Vocabulary, start: Pose = (0.0, 0.0, 0.0), resolution: float = 0.05
    ) -> None:
        self.slam = VisualSlam(vocabulary, start)
        self.vocabulary = vocabulary
        self.resolution = resolution
        self.scans: list[Scan] = []  # one per keyframe, in its robot frame
        self.clouds: list[KeyframeCloud] = []  # one per keyframe, in its robot frame
        self.stats = VisualMapStats()
        self.last_stamp = -math.inf
        self._log_odds: LogOddsGrid | None = None
        self._grid_poses: list[Pose] = []  # the pose each keyframe was added to the grid at
        self._blobs: weakref.WeakKeyDictionary[Features, bytes] = weakref.WeakKeyDictionary()

    @property
    def pose(self) -> Pose:
        return self.slam.pose

    @property
    def path(self) -> list[Pose]:
        """The keyframes' optimised poses, oldest first: the corrected path."""
        return [k.pose for k in self.slam.keyframes]

    def add(self, frame: Frame, colour: Colour | None = None) -> None:
        """Track ``frame`` and grow the map with it (a keyframe's cloud coloured by
        ``colour``, else grey). Raises KeyframeError (changing nothing) for a frame out of
        order or whose depth does not match its image."""
        try:
            self._check_order(frame.stamp)
            self.slam.intrinsics = frame.intrinsics
            tracked = self.slam.track(frame.image, frame.depth, frame.odometry)
        except KeyframeError:
            self.stats.refused += 1
            raise
        self.last_stamp = frame.stamp
        self._count(tracked.state, tracked.loop_closed)
        if tracked.keyframe:
            self.scans.append(obstacle_scan(frame.depth, frame.intrinsics, self.slam.mount))
            self.clouds.append(
                keyframe_cloud(
                    frame.depth,
                    frame.intrinsics,
                    self.slam.mount,
                    colour() if colour is not None else None,
                    frame.image,
                )
            )
            self.stats.keyframes += 1

    def _check_order(self, stamp: float) -> None:
        if not stamp > self.last_stamp:
            raise KeyframeError(
                "header.stamp",
                f"a frame of {stamp:.3f} s after one of {self.last_stamp:.3f} s: "
                "frames must come in order",
            )

    def _count(self, state: State, loop_closed: bool) -> None:
        self.stats.frames += 1
        self.stats.tracked += state is State.TRACKING
        self.stats.relocalised += state is State.RELOCALISED
        self.stats.lost += state is State.LOST
        self.stats.restarted += state is State.RESTARTED
        self.stats.loop_closures += loop_closed

    def grid(self) -> tuple[Grid, tuple[float, float]]:
        """The occupancy grid of the keyframes' depth at their optimised poses, each
        within ``GRID_TOLERANCE`` of it: the new keyframes added to the grid so far, or
        all of them again once a loop closure has moved one farther than that."""
        path = self.path
        if self._log_odds is None or self._grid_moved(path):
            self._log_odds = LogOddsGrid(SlamParams(resolution=self.resolution), None)
            self._grid_poses = []
        added = len(self._grid_poses)
        for pose, scan in zip(path[added:], self.scans[added:], strict=True):
            self._log_odds.add_view(pose, scan)
            self._grid_poses.append(pose)
        return self._log_odds.grid()

    def _grid_moved(self, path: list[Pose]) -> bool:
        """Whether a keyframe in the grid is now farther than ``GRID_TOLERANCE`` from
        where it was added."""
        return any(
            math.dist(now[:2], added[:2]) > GRID_TOLERANCE[0]
            or angle_between(now[2], added[2]) > GRID_TOLERANCE[1]
            for now, added in zip(path, self._grid_poses, strict=False)
        )

    def keyframes(self) -> list[Features]:
        """The keyframes at their optimised poses: the sub-map's relocalisation map."""
        return self.slam.keyframes

    @property
    def loops(self) -> list[tuple[int, int]]:
        """The keyframes (by position, oldest first) each loop closure joined."""
        return [(i, j) for i, j, _rel, _sig, loop in self.slam.edges if loop]

    # --- resuming ---------------------------------------------------------------------

    def state(self) -> bytes:
        """Keyframes, their scans and clouds, the graph's edges and the pose as ``.npz``
        bytes (no pickle): what ``resumed``, publishing and the 3D maps read."""
        blobs = [self._bytes_of(k) for k in self.slam.keyframes]
        beams = max((len(s.ranges) for s in self.scans), default=0)
        ranges = np.full((len(self.scans), beams), np.nan)
        angles = np.full((len(self.scans), beams), np.nan)
        for row, scan in enumerate(self.scans):
            ranges[row, : len(scan.ranges)] = scan.ranges
            angles[row, : len(scan.angles)] = scan.angles
        edges = [(i, j, *rel, *sig, float(loop)) for i, j, rel, sig, loop in self.slam.edges]
        cloud_points, cloud_colours, cloud_sizes = cloud_arrays(self.clouds)
        out = io.BytesIO()
        np.savez(  # the keyframes are compressed already; the rest is small
            out,
            blobs=np.frombuffer(b"".join(blobs), np.uint8),
            sizes=np.array([len(b) for b in blobs], np.int64),
            ranges=ranges,
            angles=angles,
            edges=np.array(edges, np.float64).reshape(-1, 9),
            travelled=np.array(self.slam.travelled_at, np.float64),
            pose=np.array(self.pose, np.float64),
            last_stamp=np.array(self.last_stamp),
            keyframe_poses=np.array(self.path, np.float64).reshape(-1, 3),
            loops=np.array(self.loops, np.int64).reshape(-1, 2),
            cloud_points=cloud_points,
            cloud_colours=cloud_colours,
            cloud_sizes=cloud_sizes,
        )
        return out.getvalue()

    def _bytes_of(self, keyframe: Features) -> bytes:
        """``keyframe.to_bytes()``, made once per keyframe (a loop closure makes new ones)."""
        found = self._blobs.get(keyframe)
        if found is None:
            found = self._blobs[keyframe] = keyframe.to_bytes()
        return found

    @classmethod
    def resumed(cls, data: bytes, vocabulary: Vocabulary, resolution: float = 0.05) -> VisualMapper:
        """A mapper holding what ``state`` saved. Raises ValueError for other bytes."""
        try:
            with np.load(io.BytesIO(data), allow_pickle=False) as saved:
                keyframes = stored_keyframes(data)
                scans = [_scan(r, a) for r, a in zip(saved["ranges"], saved["angles"], strict=True)]
                edges = [_edge(row) for row in saved["edges"]]
                travelled = [float(v) for v in saved["travelled"]]
                pose = _pose(saved["pose"])
                last_stamp = float(saved["last_stamp"])
                clouds = stored_clouds(data)
        except (OSError, KeyError, ValueError, TypeError, KeyframeError) as error:
            raise ValueError(f"not a saved visual mapping state: {error}") from None
        mapper = cls(vocabulary, pose, resolution)
        mapper.slam = VisualSlam.resumed(vocabulary, keyframes, edges, travelled, pose)
        mapper.scans, mapper.last_stamp = scans, last_stamp
        mapper.clouds = clouds if len(clouds) == len(keyframes) else []
        mapper.stats.keyframes = len(keyframes)
        return mapper


def stored_keyframes(data: bytes) -> list[Features]:
    """The keyframes a ``VisualMapper.state`` holds. Raises ValueError or KeyframeError
    for other bytes."""
    with np.load(io.BytesIO(data), allow_pickle=False) as saved:
        blob, sizes = saved["blobs"].tobytes(), saved["sizes"]
    ends = np.cumsum(sizes)
    pieces = zip(sizes, ends, strict=True)
    return [Features.from_bytes(blob[end - size : end]) for size, end in pieces]


def cloud_arrays(clouds: list[KeyframeCloud]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The keyframes' clouds as the arrays ``state`` saves: points as float16 (robot
    frame, within 8 m: steps of 4 mm at most, a tenth of a voxel), colours, sizes."""
    whole = KeyframeCloud.empty()
    points: list[np.ndarray] = [c.points for c in clouds] or [whole.points]
    colours: list[np.ndarray] = [c.colours for c in clouds] or [whole.colours]
    sizes = np.array([len(c) for c in clouds], np.int64)
    return np.concatenate(points).astype(np.float16), np.concatenate(colours), sizes


@dataclass(frozen=True)
class SavedView:
    """What the 3D maps need of a saved state: each keyframe's cloud (robot frame), its
    optimised pose, and the keyframes (by position) each loop closure joined."""

    clouds: list[KeyframeCloud]
    poses: list[Pose]
    loops: list[tuple[int, int]]


def stored_view(data: bytes) -> SavedView:
    """The ``SavedView`` of a ``VisualMapper.state`` (empty for a state saved before
    clouds were kept). Raises ValueError for other bytes."""
    try:
        with np.load(io.BytesIO(data), allow_pickle=False) as saved:
            if "cloud_sizes" not in saved.files:
                return SavedView([], [], [])
            poses = [_pose(row) for row in saved["keyframe_poses"]]
            loops = [(int(i), int(j)) for i, j in saved["loops"]]
        clouds = stored_clouds(data)
    except (OSError, KeyError, ValueError, TypeError) as error:
        raise ValueError(f"not a saved visual mapping state: {error}") from None
    if len(clouds) != len(poses):
        raise ValueError("not a saved visual mapping state: a cloud for each keyframe is needed")
    return SavedView(clouds, poses, loops)


def stored_clouds(data: bytes) -> list[KeyframeCloud]:
    """The keyframes' clouds a ``VisualMapper.state`` holds (none in a state saved before
    they were kept). Raises ValueError or KeyError for other bytes."""
    with np.load(io.BytesIO(data), allow_pickle=False) as saved:
        if "cloud_sizes" not in saved.files:
            return []
        points = np.asarray(saved["cloud_points"], np.float32).reshape(-1, 3)
        colours = np.asarray(saved["cloud_colours"], np.uint8).reshape(-1, 3)
        sizes = saved["cloud_sizes"]
    if int(sizes.sum()) != len(points) or len(points) != len(colours) or (sizes < 0).any():
        raise ValueError("the clouds' sizes do not match their points")
    ends = np.cumsum(sizes)
    return [
        KeyframeCloud(points[end - size : end], colours[end - size : end])
        for size, end in zip(sizes, ends, strict=True)
    ]


def _scan(ranges: np.ndarray, angles: np.ndarray) -> Scan:
    kept = ~np.isnan(angles)
    return Scan(angles[kept], ranges[kept])


def _edge(row: np.ndarray) -> Edge:
    return (int(row[0]), int(row[1]), _pose(row[2:5]), _pose(row[5:8]), bool(row[8]))


def _pose(values: np.ndarray) -> Pose:
    return (float(values[0]), float(values[1]), float(values[2]))
