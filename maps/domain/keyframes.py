"""Keyframes of the cloud's visual map: ORB features of a camera frame with their 3D
positions in the sub-map's frame, and a global descriptor to find them again.

A keyframe is taken from a colour (grey) image, its registered depth (metres along the
optical axis) and the robot's pose ``(x, y, yaw)`` in the sub-map. The camera sits
``Mount.forward`` metres ahead of the robot's centre and ``Mount.height`` above the
floor, looking level along the robot's heading (the simulated robot's and a TurtleBot's
Xtion). Each ORB keypoint with a trustworthy depth (within ``DEPTH_RANGE`` and not on a
depth edge) becomes a 3D point: ``x, y`` on the floor plan and ``z`` above the floor.

The global descriptor is a bag of binary words (``vocabulary``): each descriptor votes
for its nearest word, the histogram is weighted by the words' inverse document
frequency and scaled to unit length, so two views of the same place have a dot product
near 1 and unrelated views near 0.

Nothing here imports Django: the server runs it in its ingestion worker and its
relocalisation service, and benchmarks and tests run it directly.
"""

from __future__ import annotations

import io
import math
from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from cloudnav_core.camera import Intrinsics, Mount
from maps.domain.vocabulary import Vocabulary
from maps.exceptions import KeyframeError, said

Image = NDArray[np.uint8]
Depth = NDArray[np.float32]

ORB_FEATURES = 600
"""Keypoints ORB keeps per frame (strongest first)."""
DEPTH_RANGE = (0.3, 8.0)
"""Metres: depth readings outside this are not trusted (an Xtion's working range)."""
DEPTH_EDGE = 0.05
"""Relative depth spread in a keypoint's 5x5 neighbourhood beyond which it sits on an
edge (a door frame's side, a wall's end) and its depth could belong to either side."""
MIN_POINTS = 20
"""A keyframe with fewer 3D points than this is not worth keeping."""
DUPLICATE_DISTANCE = 0.15
"""Metres: a keyframe this near one already kept, facing within ``DUPLICATE_YAW``..."""
DUPLICATE_YAW = math.radians(10.0)
"""...adds nothing to a relocalisation map and is dropped."""


@dataclass(frozen=True, eq=False)
class Keyframe:
    """Features of one frame: ``descriptors`` (n x 32 ORB), ``points`` (n x 3, sub-map
    frame: x, y on the plan, z above the floor), ``words`` (the global descriptor), and
    the robot ``pose`` it was taken from."""

    pose: tuple[float, float, float]
    descriptors: Image
    points: NDArray[np.float32]
    words: NDArray[np.float32]

    def to_bytes(self) -> bytes:
        """The keyframe as a compressed ``.npz`` (what the server writes to disk)."""
        buffer = io.BytesIO()
        np.savez_compressed(
            buffer,
            pose=np.array(self.pose, np.float64),
            descriptors=self.descriptors,
            points=self.points.astype(np.float32),
            words=self.words.astype(np.float16),
        )
        return buffer.getvalue()

    @classmethod
    def from_bytes(cls, data: bytes) -> Keyframe:
        """Read ``to_bytes``'s output; raises KeyframeError for anything else."""
        try:
            with np.load(io.BytesIO(data), allow_pickle=False) as stored:
                pose = tuple(float(v) for v in stored["pose"])
                keyframe = cls(
                    (pose[0], pose[1], pose[2]),
                    np.asarray(stored["descriptors"], np.uint8),
                    np.asarray(stored["points"], np.float32),
                    np.asarray(stored["words"], np.float32),
                )
        except (OSError, ValueError, KeyError, IndexError) as error:
            raise KeyframeError("keyframe", f"a file that cannot be read: {said(error)}") from None
        if not all(np.isfinite(a).all() for a in (keyframe.pose, keyframe.points, keyframe.words)):
            raise KeyframeError("keyframe", "a file whose pose, points or words are not finite")
        return keyframe


def duplicates(kept: tuple[float, float, float], pose: tuple[float, float, float]) -> bool:
    """Whether a keyframe kept at ``kept`` makes one at ``pose`` a near-duplicate: within
    ``DUPLICATE_DISTANCE`` of it, facing within ``DUPLICATE_YAW``."""
    return (
        math.hypot(kept[0] - pose[0], kept[1] - pose[1]) <= DUPLICATE_DISTANCE
        and abs(math.remainder(kept[2] - pose[2], math.tau)) <= DUPLICATE_YAW
    )


def thinned(keyframes: list[Keyframe]) -> list[Keyframe]:
    """``keyframes`` in order without the near-duplicates of those kept before them: what
    storing them one by one in an empty sub-map keeps (``maps.visual.store.save``)."""
    kept: list[Keyframe] = []
    for keyframe in keyframes:
        if not any(duplicates(k.pose, keyframe.pose) for k in kept):
            kept.append(keyframe)
    return kept


class FeatureExtractor:
    """ORB keypoints and descriptors of grey images, and their bag of ``vocabulary``
    words. One per thread (OpenCV's detector is not shared across threads)."""

    def __init__(self, vocabulary: Vocabulary, features: int = ORB_FEATURES) -> None:
        self.vocabulary = vocabulary
        self.orb = cv2.ORB.create(features, scaleFactor=1.2, nlevels=8, fastThreshold=12)

    def detect(self, image: Image) -> tuple[NDArray[np.float32], Image]:
        """Keypoint pixels (n x 2) and their descriptors (n x 32) of a grey image."""
        keypoints, descriptors = self.orb.detectAndCompute(image, None)
        if descriptors is None or not keypoints:
            return np.zeros((0, 2), np.float32), np.zeros((0, 32), np.uint8)
        pixels = np.array([k.pt for k in keypoints], np.float32)
        return pixels, np.asarray(descriptors, np.uint8)

    def keyframe(
        self,
        image: Image,
        depth: Depth,
        pose: tuple[float, float, float],
        intrinsics: Intrinsics | None = None,
        mount: Mount | None = None,
    ) -> Keyframe:
        """The keyframe of ``image`` with registered ``depth`` taken at robot ``pose``.

        Raises KeyframeError when the two images differ in size or too few keypoints
        have a usable depth.
        """
        if image.shape[:2] != depth.shape[:2]:
            raise KeyframeError(
                "depth",
                f"the depth image is {depth.shape[1]}x{depth.shape[0]}, "
                f"the colour image {image.shape[1]}x{image.shape[0]}: they must match",
            )
        pixels, descriptors = self.detect(image)
        usable, metres = _usable_depth(pixels, depth)
        if int(usable.sum()) < MIN_POINTS:
            raise KeyframeError(
                "depth",
                f"only {int(usable.sum())} features have a usable depth (at least "
                f"{MIN_POINTS} are needed): a blank or too distant view",
            )
        intrinsics = intrinsics or Intrinsics(image.shape[1], image.shape[0])
        points = back_project(pixels[usable], metres[usable], pose, intrinsics, mount or Mount())
        if not np.isfinite(points).all():
            raise KeyframeError("pose", "the keyframe's 3D points are not all finite numbers")
        descriptors = descriptors[usable]
        return Keyframe(pose, descriptors, points, self.vocabulary.bag(descriptors))


def _usable_depth(pixels: NDArray[np.float32], depth: Depth) -> tuple[NDArray[np.bool_], Depth]:
    """Which keypoints have a depth in range off any depth edge, and that depth."""
    if pixels.shape[0] == 0:
        return np.zeros(0, bool), np.zeros(0, np.float32)
    clean = np.where(np.isfinite(depth), depth, 0.0).astype(np.float32)
    kernel = np.ones((5, 5), np.uint8)
    low = cv2.erode(np.where(clean > 0, clean, np.float32(1e6)).astype(np.float32), kernel)
    high = cv2.dilate(clean, kernel)
    cols = np.clip(np.rint(pixels[:, 0]).astype(np.intp), 0, depth.shape[1] - 1)
    rows = np.clip(np.rint(pixels[:, 1]).astype(np.intp), 0, depth.shape[0] - 1)
    metres = clean[rows, cols]
    steady = (high[rows, cols] - low[rows, cols]) <= DEPTH_EDGE * np.maximum(metres, 1e-6)
    in_range = (metres >= DEPTH_RANGE[0]) & (metres <= DEPTH_RANGE[1])
    return steady & in_range, metres


def back_project(
    pixels: NDArray[np.float32],
    depth: NDArray[np.float32],
    pose: tuple[float, float, float],
    intrinsics: Intrinsics,
    mount: Mount,
) -> NDArray[np.float32]:
    """3D points (sub-map frame) of ``pixels`` seen at ``depth`` from robot ``pose``."""
    z = depth.astype(np.float64)
    right = (pixels[:, 0] - intrinsics.cx) * z / intrinsics.fx
    down = (pixels[:, 1] - intrinsics.cy) * z / intrinsics.fy
    forward, left = z + mount.forward, -right
    c, s = math.cos(pose[2]), math.sin(pose[2])
    x = pose[0] + c * forward - s * left
    y = pose[1] + s * forward + c * left
    return np.stack([x, y, mount.height - down], axis=1).astype(np.float32)


def camera_matrix_of(pose: tuple[float, float, float], mount: Mount) -> tuple[Any, Any]:
    """``(rvec, tvec)`` of the camera of a robot at ``pose`` (world to optical frame)."""
    c, s = math.cos(pose[2]), math.sin(pose[2])
    centre = np.array([pose[0] + mount.forward * c, pose[1] + mount.forward * s, mount.height])
    # Rows: the optical frame's axes (right, down, forward) in the world.
    rotation = np.array([[s, -c, 0.0], [0.0, 0.0, -1.0], [c, s, 0.0]])
    rvec, _ = cv2.Rodrigues(rotation)
    return rvec, -rotation @ centre
