"""A visual mapping session's map: the tracking core (``visual_slam``) fed with a robot's
camera frames, the obstacle scan of each keyframe's depth for the 2D grid
(``visual_grid``), the figures the session shows, and the state a stopped session resumes
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
from dataclasses import dataclass
from typing import Any

import numpy as np

from maps.domain.keyframes import Depth, Image, Intrinsics
from maps.domain.keyframes import Keyframe as Features
from maps.domain.slam import Grid, LogOddsGrid, Scan, SlamParams
from maps.domain.visual_grid import obstacle_scan
from maps.domain.visual_input import depth_image, finite_depth, grey_image, intrinsics_of, stamp_of
from maps.domain.visual_slam import Edge, State, VisualSlam
from maps.domain.vocabulary import Vocabulary
from maps.exceptions import KeyframeError
from robots.domain.se2 import Pose


@dataclass
class VisualMapStats:
    """What the session did, for its page (the laser mapper's ``MapStats`` of a camera)."""

    frames: int = 0
    tracked: int = 0
    relocalised: int = 0
    lost: int = 0
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


class VisualMapper:
    """Builds one map from a stream of ``Frame``s."""

    def __init__(
        self, vocabulary: Vocabulary, start: Pose = (0.0, 0.0, 0.0), resolution: float = 0.05
    ) -> None:
        self.slam = VisualSlam(vocabulary, start)
        self.vocabulary = vocabulary
        self.resolution = resolution
        self.scans: list[Scan] = []  # one per keyframe, in its robot frame
        self.stats = VisualMapStats()
        self.last_stamp = -math.inf
        self._log_odds: LogOddsGrid | None = None  # made again after a loop closure
        self._in_grid = 0  # keyframes the log-odds grid holds
        self._blobs: weakref.WeakKeyDictionary[Features, bytes] = weakref.WeakKeyDictionary()

    @property
    def pose(self) -> Pose:
        return self.slam.pose

    @property
    def path(self) -> list[Pose]:
        """The keyframes' optimised poses, oldest first: the corrected path."""
        return [k.pose for k in self.slam.keyframes]

    def add(self, frame: Frame) -> None:
        """Track ``frame`` and grow the map with it. Raises KeyframeError (changing
        nothing) for a frame out of order or whose depth does not match its image."""
        try:
            self._check_order(frame.stamp)
            self.slam.intrinsics = frame.intrinsics
            tracked = self.slam.track(frame.image, frame.depth, frame.odometry)
        except KeyframeError:
            self.stats.refused += 1
            raise
        self.last_stamp = frame.stamp
        self._count(tracked.state, tracked.loop_closed)
        if tracked.loop_closed:
            self._log_odds = None  # the keyframes moved
        if tracked.keyframe:
            self.scans.append(obstacle_scan(frame.depth, frame.intrinsics, self.slam.mount))
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
        self.stats.loop_closures += loop_closed

    def grid(self) -> tuple[Grid, tuple[float, float]]:
        """The occupancy grid of the keyframes' depth at their optimised poses: the new
        keyframes added to the grid so far, or all of them again after a loop closure."""
        if self._log_odds is None:
            self._log_odds = LogOddsGrid(SlamParams(resolution=self.resolution), None)
            self._in_grid = 0
        views = list(zip(self.path, self.scans, strict=True))
        for pose, scan in views[self._in_grid :]:
            self._log_odds.add_view(pose, scan)
        self._in_grid = len(views)
        return self._log_odds.grid()

    def keyframes(self) -> list[Features]:
        """The keyframes at their optimised poses: the sub-map's relocalisation map."""
        return self.slam.keyframes

    # --- resuming ---------------------------------------------------------------------

    def state(self) -> bytes:
        """Keyframes, their scans, the graph's edges and the pose as ``.npz`` bytes (no
        pickle): what ``resumed`` and publishing read."""
        blobs = [self._bytes_of(k) for k in self.slam.keyframes]
        beams = max((len(s.ranges) for s in self.scans), default=0)
        ranges = np.full((len(self.scans), beams), np.nan)
        angles = np.full((len(self.scans), beams), np.nan)
        for row, scan in enumerate(self.scans):
            ranges[row, : len(scan.ranges)] = scan.ranges
            angles[row, : len(scan.angles)] = scan.angles
        edges = [(i, j, *rel, *sig, float(loop)) for i, j, rel, sig, loop in self.slam.edges]
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
        except (OSError, KeyError, ValueError, TypeError, KeyframeError) as error:
            raise ValueError(f"not a saved visual mapping state: {error}") from None
        mapper = cls(vocabulary, pose, resolution)
        mapper.slam = VisualSlam.resumed(vocabulary, keyframes, edges, travelled, pose)
        mapper.scans, mapper.last_stamp = scans, last_stamp
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


def _scan(ranges: np.ndarray, angles: np.ndarray) -> Scan:
    kept = ~np.isnan(angles)
    return Scan(angles[kept], ranges[kept])


def _edge(row: np.ndarray) -> Edge:
    return (int(row[0]), int(row[1]), _pose(row[2:5]), _pose(row[5:8]), bool(row[8]))


def _pose(values: np.ndarray) -> Pose:
    return (float(values[0]), float(values[1]), float(values[2]))
