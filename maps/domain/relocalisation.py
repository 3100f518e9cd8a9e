"""Where a camera image was taken, from the keyframes of a building: retrieval, then
feature matching, then ``solvePnPRansac`` and a planar refinement.

1. **Retrieval**: the query's bag of words against every keyframe's (one matrix
   product); the ``Params.candidates`` best keyframes go on.
2. **Matching**: the query's ORB descriptors against each candidate's, nearest two by
   Hamming distance, kept when the nearest is clearly nearer (Lowe's ratio); each match
   pairs a query pixel with a 3D point of the sub-map.
3. **Pose** (``solvePnPRansac``'s job, in the plane): per sub-map among the
   candidates, RANSAC over all its matches. A robot's camera is level at a known
   height, so the pose has three unknowns (x, y, yaw) and two matches fix it
   (``_planar_ransac``): a perspective-n-point problem solved with that constraint,
   which also leaves chance matches far less room to agree than a free 6-DoF
   ``solvePnPRansac`` would. The pose is refined (Gauss-Newton on the inliers'
   reprojection error, Huber-weighted), and its covariance is the inverse information
   of that fit, scaled by the residuals and inflated for the keyframes' own pose error,
   plus the spread of the RANSAC poses nearly as well supported as the best
   (``_with_rivals``): where the inliers' geometry leaves a direction loose, or some
   keyframe's points are off, those poses lie apart and the covariance says so.
   Last, ``solvePnPRansac`` on the inliers alone (free in 6 DoF) must agree that the
   camera is level at its height.

"Not localised", with the reason, whenever the evidence is weak: too few matches or
inliers (counted once per query pixel), inliers all on one small part of the image (one
thing, whose look may repeat anywhere), a free pose that is no robot's camera, or a
covariance too wide. Images of a place the keyframes do not show find only chance
matches, which no level pose at the camera's height explains together.

Nothing here imports Django.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import cv2
import numpy as np
from numpy.typing import NDArray

from cloudnav_core.camera import Intrinsics, Mount
from maps.domain.keyframes import Image, Keyframe
from maps.domain.vocabulary import Vocabulary

Covariance = NDArray[np.float64]


@dataclass(frozen=True)
class Params:
    candidates: int = 8
    """Keyframes retrieval passes to matching."""
    ratio: float = 0.8
    """Lowe's ratio: nearest over second-nearest Hamming distance at most this."""
    reprojection: float = 4.0
    """Pixels: RANSAC's inlier threshold."""
    iterations: int = 300
    """Pairs of matches RANSAC hypothesises a pose from."""
    min_matches: int = 20
    min_inliers: int = 40
    """Distinct query pixels among the inliers needed for an answer."""
    grid: tuple[int, int] = (8, 6)
    """Cells across and down the image (80 px squares at 640x480) ``min_cells`` counts."""
    min_cells: int = 4
    """Cells of ``grid`` the inliers must fall in: inliers all on one small thing (a tag,
    a sign: one or two cells where a robot sees it) fit a level pose as well as a whole
    wall does and give as tight a covariance, but that thing's look repeats elsewhere
    (every tag's marker, another building's), so it places no one."""
    max_tilt: float = math.radians(8.0)
    """A free (6-DoF) pose of the inliers tilted more than this is no robot's camera."""
    max_height_error: float = 0.15
    """Metres between that pose's camera height and the mount's."""
    max_position_sigma: float = 0.25
    """Metres: an answer less certain than this is not given."""
    inflation: float = 9.0
    """Factor on the fit's covariance (matches are not independent: neighbouring pixels
    share blur and depth error)."""
    floor: tuple[float, float, float] = (0.03, 0.03, math.radians(0.8))
    """Standard deviations added for the keyframes' own pose error (x, y, yaw)."""
    rival_share: float = 0.7
    """A pose that this share of the answer's support agrees with is a rival explanation
    of the matches: the covariance must cover it (``_with_rivals``)."""
    rivals: int = 4
    """RANSAC hypotheses refined as candidate rivals, per query and sub-map."""
    rival_chi2: float = 11.34
    """Squared Mahalanobis distance (chi-square, 3 DoF, 99 %) past which a pose lies
    outside a covariance."""
    solver: str = "level"
    """How the pose is hypothesised: ``level`` (``_planar_ransac``) or ``opencv``
    (``_pnp_ransac``: OpenCV's free 6-DoF ``solvePnPRansac``), refined and checked alike;
    ``bench relocalise --solver`` compares them (docs/design.md)."""


@dataclass(frozen=True)
class QueryFrame:
    """One query image's keypoint pixels (n x 2), descriptors and bag of words."""

    pixels: NDArray[np.float32]
    descriptors: Image
    words: NDArray[np.float32]


@dataclass(frozen=True)
class Answer:
    """``localised`` with ``submap`` (its code), the robot's ``pose`` in it,
    ``covariance`` (3x3 over x, y, yaw), ``inliers``, the ``keyframes`` (ids) that
    matched and the ``image`` (index in the query) the pose is of; else ``reason``."""

    localised: bool
    reason: str = ""
    submap: str = ""
    pose: tuple[float, float, float] = (0.0, 0.0, 0.0)
    covariance: Covariance = field(default_factory=lambda: np.zeros((3, 3)))
    inliers: int = 0
    keyframes: tuple[int, ...] = ()
    image: int = 0


class KeyframeIndex:
    """The keyframes of one building, searchable: ids, sub-map codes, bags of words."""

    def __init__(self, vocabulary_size: int) -> None:
        self.ids: list[int] = []
        self.submaps: list[str] = []
        self.frames: list[Keyframe] = []
        self._words = np.zeros((0, vocabulary_size), np.float32)
        self._pending: list[NDArray[np.float32]] = []

    def __len__(self) -> int:
        return len(self.ids)

    def add(self, keyframe_id: int, submap: str, keyframe: Keyframe) -> None:
        self.ids.append(keyframe_id)
        self.submaps.append(submap)
        self.frames.append(keyframe)
        self._pending.append(keyframe.words.astype(np.float32))

    def nearest(self, words: NDArray[np.float32], count: int, submap: str = "") -> list[int]:
        """Positions of the ``count`` keyframes whose words best match (in ``submap``
        only, when given)."""
        if self._pending:
            self._words = np.vstack([self._words, *self._pending])
            self._pending = []
        if not self.ids:
            return []
        scores = self._words @ words
        if submap:
            scores = np.where(np.array(self.submaps) == submap, scores, -1.0)
        order = np.argsort(-scores)[:count]
        return [int(i) for i in order if scores[i] > 0]


def query_frame(
    extractor_detect: tuple[NDArray[np.float32], Image], vocabulary: Vocabulary
) -> QueryFrame:
    """A ``QueryFrame`` from a detector's ``(pixels, descriptors)``."""
    pixels, descriptors = extractor_detect
    return QueryFrame(pixels, descriptors, vocabulary.bag(descriptors))


def relocalise(
    index: KeyframeIndex,
    frames: Sequence[QueryFrame],
    intrinsics: Intrinsics,
    mount: Mount,
    submap: str = "",
    params: Params | None = None,
) -> Answer:
    """The best answer over the query ``frames`` (the one with most inliers), or the
    first frame's reason when none localises."""
    params = params or Params()
    if len(index) == 0:
        return Answer(False, "no keyframes are stored for this building yet")
    answers = [
        _with_image(_one(index, frame, intrinsics, mount, submap, params), i)
        for i, frame in enumerate(frames)
    ]
    found = [a for a in answers if a.localised]
    if found:
        return max(found, key=lambda a: a.inliers)
    return max(answers, key=lambda a: a.inliers)


def _with_image(answer: Answer, image: int) -> Answer:
    return Answer(**{**answer.__dict__, "image": image})


@dataclass
class _Matches:
    pixels: list[NDArray[np.float32]] = field(default_factory=list)
    points: list[NDArray[np.float32]] = field(default_factory=list)
    query: list[NDArray[np.intp]] = field(default_factory=list)
    keyframes: list[NDArray[np.intp]] = field(default_factory=list)


def _one(
    index: KeyframeIndex,
    frame: QueryFrame,
    intrinsics: Intrinsics,
    mount: Mount,
    submap: str,
    params: Params,
) -> Answer:
    if frame.descriptors.shape[0] < params.min_matches:
        return Answer(
            False, f"the image shows too little texture ({frame.descriptors.shape[0]} features)"
        )
    by_submap = _matches(
        index, frame, index.nearest(frame.words, params.candidates, submap), params
    )
    if not by_submap:
        return Answer(False, "no stored keyframe resembles the image")
    answers = [
        _solve(code, matches, intrinsics, mount, params) for code, matches in by_submap.items()
    ]
    return max(answers, key=lambda a: (a.localised, a.inliers))


def _matches(
    index: KeyframeIndex, frame: QueryFrame, candidates: list[int], params: Params
) -> dict[str, _Matches]:
    """Ratio-test matches of ``frame`` with each candidate, grouped by sub-map."""
    matcher = cv2.BFMatcher(cv2.NORM_HAMMING)
    grouped: dict[str, _Matches] = {}
    for position in candidates:
        keyframe = index.frames[position]
        if keyframe.descriptors.shape[0] < 2:
            continue
        pairs = matcher.knnMatch(frame.descriptors, keyframe.descriptors, k=2)
        good = [
            (p[0].queryIdx, p[0].trainIdx)
            for p in pairs
            if len(p) == 2 and p[0].distance <= params.ratio * p[1].distance
        ]
        if not good:
            continue
        query, train = (np.array(side, np.intp) for side in zip(*good, strict=True))
        group = grouped.setdefault(index.submaps[position], _Matches())
        group.pixels.append(frame.pixels[query])
        group.points.append(keyframe.points[train])
        group.query.append(query)
        group.keyframes.append(np.full(query.size, index.ids[position], np.intp))
    return grouped


def _solve(
    code: str,
    matches: _Matches,
    intrinsics: Intrinsics,
    mount: Mount,
    params: Params,
) -> Answer:
    pixels = np.concatenate(matches.pixels).astype(np.float64)
    points = np.concatenate(matches.points).astype(np.float64)
    query = np.concatenate(matches.query)
    distinct = np.unique(query).size
    if distinct < params.min_matches:
        return Answer(False, f"too few feature matches ({distinct})", code, inliers=0)
    rng = np.random.default_rng(distinct)  # the same query answers the same
    if params.solver == "opencv":
        hypotheses = _pnp_ransac(pixels, points, intrinsics, mount, params)
    else:
        hypotheses = _planar_ransac(pixels, points, intrinsics, mount, params, rng)
    if hypotheses is None:
        return Answer(False, f"no pose explains the {distinct} matches", code)
    poses, support = hypotheses
    best = int(np.argmax(support))
    level = (float(poses[best, 0]), float(poses[best, 1]), float(poses[best, 2]))
    pose, kept = _refine(level, pixels, points, intrinsics, mount, params)
    free = _free_pose_check(pixels[kept], points[kept], intrinsics, mount, params)
    if free:
        return Answer(False, free, code, inliers=int(np.unique(query[kept]).size))
    count = np.unique(query[kept]).size
    if count < params.min_inliers:
        return Answer(False, f"too few inliers after refinement ({count})", code, inliers=count)
    cells = _cells(pixels[kept], intrinsics, params.grid)
    if cells < params.min_cells:
        return Answer(
            False,
            f"the inliers lie on one small part of the image ({cells} of its "
            f"{params.grid[0] * params.grid[1]} cells): one thing, which may be anywhere",
            code,
            inliers=count,
        )
    covariance = _covariance(pose, pixels[kept], points[kept], intrinsics, mount, params)
    covariance = _with_rivals(
        pose, kept, covariance, (poses, support), (pixels, points), intrinsics, mount, params
    )
    sigma = math.sqrt(covariance[0, 0] + covariance[1, 1])
    if sigma > params.max_position_sigma:
        return Answer(False, f"the pose is too uncertain ({sigma:.2f} m)", code, inliers=count)
    keyframes = tuple(int(k) for k in np.unique(np.concatenate(matches.keyframes)[kept]))
    return Answer(True, "", code, pose, covariance, count, keyframes)


def _cells(pixels: NDArray[np.float64], intrinsics: Intrinsics, grid: tuple[int, int]) -> int:
    """How many cells of a ``grid`` (across, down) over the image hold some of ``pixels``."""
    across = np.clip(pixels[:, 0] * grid[0] // intrinsics.width, 0, grid[0] - 1)
    down = np.clip(pixels[:, 1] * grid[1] // intrinsics.height, 0, grid[1] - 1)
    return int(np.unique(down * grid[0] + across).size)


def _planar_ransac(
    pixels: NDArray[np.float64],
    points: NDArray[np.float64],
    intrinsics: Intrinsics,
    mount: Mount,
    params: Params,
    rng: np.random.Generator,
) -> tuple[NDArray[np.float64], NDArray[np.intp]] | None:
    """Robot poses hypothesised by RANSAC over pairs of matches, and each one's support
    (the matches it reprojects within ``params.reprojection``).

    The camera is level at ``mount.height``, so a pixel's row gives the range of the 3D
    point it sees (how far below or above the horizon that height difference appears),
    and its column the bearing: each match places its point in the robot's frame, and
    two such points fix a planar pose. Every pose hypothesised is scored by reprojecting
    all matches at once; None when no hypothesis gathers ``min_inliers``."""
    local, usable = _robot_frame(pixels, points, intrinsics, mount)
    candidates = np.flatnonzero(usable)
    if candidates.size < 2:
        return None
    pairs = rng.choice(candidates, size=(params.iterations, 2))
    poses = _pair_poses(
        local[pairs[:, 0]], local[pairs[:, 1]], points[pairs[:, 0], :2], points[pairs[:, 1], :2]
    )
    if poses.shape[0] == 0:
        return None
    projected, forward = _project_many(poses, points, intrinsics, mount)
    errors = np.linalg.norm(projected - pixels[None, :, :], axis=2)
    support = ((errors <= params.reprojection) & (forward > 0.1)).sum(axis=1)
    if support.max() < params.min_inliers:
        return None
    return poses, support


def _pnp_ransac(
    pixels: NDArray[np.float64],
    points: NDArray[np.float64],
    intrinsics: Intrinsics,
    mount: Mount,
    params: Params,
) -> tuple[NDArray[np.float64], NDArray[np.intp]] | None:
    """OpenCV's ``solvePnPRansac`` (free 6 DoF, its default minimal solver and
    refinement) as the one hypothesis: its camera put on the floor plan as a robot pose
    (heading from the optical axis), with its inlier count as support; None when it
    finds no pose or fewer than ``min_inliers`` inliers."""
    ok, rvec, tvec, inliers = cv2.solvePnPRansac(
        points, pixels, intrinsics.matrix(), None, iterationsCount=params.iterations,
        reprojectionError=params.reprojection, confidence=0.999,
    )  # fmt: skip
    if not ok or inliers is None or len(inliers) < params.min_inliers:
        return None
    rotation, _ = cv2.Rodrigues(rvec)
    centre = -rotation.T @ np.asarray(tvec).ravel()
    yaw = math.atan2(float(rotation[2, 1]), float(rotation[2, 0]))
    x = float(centre[0]) - mount.forward * math.cos(yaw)
    y = float(centre[1]) - mount.forward * math.sin(yaw)
    return np.array([[x, y, yaw]]), np.array([len(inliers)], np.intp)


def _with_rivals(
    pose: tuple[float, float, float],
    kept: NDArray[np.intp],
    covariance: Covariance,
    hypotheses: tuple[NDArray[np.float64], NDArray[np.intp]],
    matches: tuple[NDArray[np.float64], NDArray[np.float64]],
    intrinsics: Intrinsics,
    mount: Mount,
    params: Params,
) -> Covariance:
    """``covariance`` widened to cover rival poses: other local optima of the fit that
    nearly as many matches agree with.

    The fit's covariance only describes pixel noise around the pose it converged to.
    When the inliers' geometry leaves a direction barely constrained (points all at one
    range in a narrow view: sliding sideways and turning trade off), or a keyframe's
    points are off (depth misread at an object's edge), poses well apart explain nearly
    as many matches, which the residuals cannot show. RANSAC's hypotheses find them: the
    ``params.rivals`` well-supported ones (``params.rival_share`` of the best's support)
    farthest outside the covariance are refined like the answer; those that stay outside
    it (Mahalanobis past ``params.rival_chi2``) keeping ``rival_share`` of its inliers
    add their second moment about the answer, so the covariance covers them, and a pose
    that could as well be 0.3 m elsewhere is "not localised"."""
    poses, support = hypotheses
    information = np.linalg.inv(covariance)
    offsets = _offsets(poses, pose)
    distance = np.einsum("ij,jk,ik->i", offsets, information, offsets)
    strong = np.flatnonzero(
        (support >= params.rival_share * support.max()) & (distance > params.rival_chi2)
    )
    farthest = strong[np.argsort(-distance[strong])][: params.rivals]
    found, weights = [], []
    for start in farthest:
        guess = (float(poses[start, 0]), float(poses[start, 1]), float(poses[start, 2]))
        rival, rival_kept = _refine(guess, *matches, intrinsics, mount, params)
        offset = _offsets(np.array([rival]), pose)[0]
        if (
            rival_kept.size >= params.rival_share * kept.size
            and offset @ information @ offset > params.rival_chi2
        ):
            found.append(offset)
            weights.append(rival_kept.size / kept.size)
    if not found:
        return covariance
    rivals = np.array(found)
    share = np.array(weights) / (1.0 + sum(weights))  # the answer itself weighs 1
    return np.asarray(covariance + (rivals * share[:, None]).T @ rivals, np.float64)


def _offsets(poses: NDArray[np.float64], pose: tuple[float, float, float]) -> NDArray[np.float64]:
    offsets = np.asarray(poses - np.array(pose)[None, :], np.float64)
    offsets[:, 2] = np.remainder(offsets[:, 2] + np.pi, 2 * np.pi) - np.pi
    return offsets


def _robot_frame(
    pixels: NDArray[np.float64], points: NDArray[np.float64], intrinsics: Intrinsics, mount: Mount
) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
    """Each match's point in the robot's frame (forward, left) as its pixel places it,
    and whether that placement is well conditioned (off the horizon, in range)."""
    below = pixels[:, 1] - intrinsics.cy
    drop = mount.height - points[:, 2]  # how far below the camera the point is
    with np.errstate(divide="ignore", invalid="ignore"):
        forward = intrinsics.fy * drop / below
    left = -forward * (pixels[:, 0] - intrinsics.cx) / intrinsics.fx
    usable = (np.abs(below) >= 12.0) & (forward > 0.2) & (forward < 10.0)
    return np.stack([forward + mount.forward, left], axis=1), usable


def _pair_poses(
    qa: NDArray[np.float64],
    qb: NDArray[np.float64],
    pa: NDArray[np.float64],
    pb: NDArray[np.float64],
) -> NDArray[np.float64]:
    """Planar poses (x, y, yaw) taking robot-frame points ``qa, qb`` onto map points
    ``pa, pb``, for the pairs whose two spans agree in length (within 10 %)."""
    q, p = qb - qa, pb - pa
    span_q, span_p = np.linalg.norm(q, axis=1), np.linalg.norm(p, axis=1)
    agree = (span_p > 0.3) & (np.abs(span_q - span_p) <= 0.1 * span_p)
    yaw = np.arctan2(p[:, 1], p[:, 0]) - np.arctan2(q[:, 1], q[:, 0])
    c, s = np.cos(yaw), np.sin(yaw)
    x = pa[:, 0] - (c * qa[:, 0] - s * qa[:, 1])
    y = pa[:, 1] - (s * qa[:, 0] + c * qa[:, 1])
    poses = np.stack([x, y, np.remainder(yaw + np.pi, 2 * np.pi) - np.pi], axis=1)
    return np.asarray(poses[agree], np.float64)


def _project_many(
    poses: NDArray[np.float64], points: NDArray[np.float64], intrinsics: Intrinsics, mount: Mount
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """``project`` for many poses at once: pixels (poses x points x 2) and forward depths."""
    c, s = np.cos(poses[:, 2])[:, None], np.sin(poses[:, 2])[:, None]
    dx = points[None, :, 0] - (poses[:, 0:1] + mount.forward * c)
    dy = points[None, :, 1] - (poses[:, 1:2] + mount.forward * s)
    forward = dx * c + dy * s
    right = dx * s - dy * c
    depth = np.maximum(forward, 1e-6)
    u = intrinsics.cx + intrinsics.fx * right / depth
    v = intrinsics.cy + intrinsics.fy * (mount.height - points[None, :, 2]) / depth
    return np.stack([u, v], axis=2), forward


def _free_pose_check(
    pixels: NDArray[np.float64],
    points: NDArray[np.float64],
    intrinsics: Intrinsics,
    mount: Mount,
    params: Params,
) -> str:
    """Why the inliers' free 6-DoF pose (``solvePnPRansac`` on them alone, so it
    converges in a few iterations) cannot be a robot's camera: tilted, or at the wrong
    height; "" when it agrees with the level camera."""
    if pixels.shape[0] < 6:
        return "too few inliers for a pose"
    ok, rvec, tvec, _ = cv2.solvePnPRansac(
        points, pixels, intrinsics.matrix(), None, iterationsCount=50,
        reprojectionError=params.reprojection, confidence=0.99, flags=cv2.SOLVEPNP_EPNP,
    )  # fmt: skip
    if not ok:
        return "the matches admit no camera pose"
    rotation, _ = cv2.Rodrigues(rvec)
    centre = -rotation.T @ np.asarray(tvec).ravel()
    right, _, forward = rotation  # the optical axes in the world
    tilt = max(abs(float(forward[2])), abs(float(right[2])))
    if tilt > math.sin(params.max_tilt):
        degrees = math.degrees(math.asin(min(tilt, 1.0)))
        return f"the matches want a tilted camera ({degrees:.0f} degrees)"
    if abs(centre[2] - mount.height) > params.max_height_error:
        return f"the matches put the camera {centre[2]:.2f} m above the floor"
    return ""


def project(
    pose: tuple[float, float, float],
    points: NDArray[np.float64],
    intrinsics: Intrinsics,
    mount: Mount,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Pixels of 3D ``points`` seen by the level camera of a robot at ``pose``, and their
    depths along the optical axis."""
    x, y, yaw = pose
    c, s = math.cos(yaw), math.sin(yaw)
    dx = points[:, 0] - (x + mount.forward * c)
    dy = points[:, 1] - (y + mount.forward * s)
    forward = dx * c + dy * s
    right = dx * s - dy * c
    down = mount.height - points[:, 2]
    depth = np.maximum(forward, 1e-6)
    u = intrinsics.cx + intrinsics.fx * right / depth
    v = intrinsics.cy + intrinsics.fy * down / depth
    return np.stack([u, v], axis=1), forward


def _residuals(
    pose: tuple[float, float, float],
    pixels: NDArray[np.float64],
    points: NDArray[np.float64],
    intrinsics: Intrinsics,
    mount: Mount,
) -> NDArray[np.float64]:
    projected, _ = project(pose, points, intrinsics, mount)
    return (projected - pixels).ravel()


def _jacobian(
    pose: tuple[float, float, float],
    pixels: NDArray[np.float64],
    points: NDArray[np.float64],
    intrinsics: Intrinsics,
    mount: Mount,
) -> NDArray[np.float64]:
    steps = (1e-4, 1e-4, 1e-5)
    base = _residuals(pose, pixels, points, intrinsics, mount)
    columns = []
    for axis, step in enumerate(steps):
        moved = list(pose)
        moved[axis] += step
        shifted = _residuals((moved[0], moved[1], moved[2]), pixels, points, intrinsics, mount)
        columns.append((shifted - base) / step)
    return np.stack(columns, axis=1)


def _refine(
    pose: tuple[float, float, float],
    pixels: NDArray[np.float64],
    points: NDArray[np.float64],
    intrinsics: Intrinsics,
    mount: Mount,
    params: Params,
) -> tuple[tuple[float, float, float], NDArray[np.intp]]:
    """Gauss-Newton in (x, y, yaw) on the matches within the RANSAC threshold of the
    current pose, Huber-weighted; returns the pose and those matches' positions."""
    kept = np.zeros(0, np.intp)
    for _ in range(6):
        errors = _residuals(pose, pixels, points, intrinsics, mount).reshape(-1, 2)
        distance = np.linalg.norm(errors, axis=1)
        kept = np.flatnonzero(distance <= params.reprojection)
        if kept.size < 3:
            break
        jacobian = _jacobian(pose, pixels[kept], points[kept], intrinsics, mount)
        weights = np.repeat(np.minimum(1.0, 1.5 / np.maximum(distance[kept], 1e-9)), 2)
        normal = jacobian.T @ (jacobian * weights[:, None])
        gradient = jacobian.T @ (weights * errors[kept].ravel())
        try:
            step = -np.linalg.solve(normal, gradient)
        except np.linalg.LinAlgError:
            break
        pose = (pose[0] + step[0], pose[1] + step[1], math.remainder(pose[2] + step[2], math.tau))
        if np.abs(step).max() < 1e-5:
            break
    return (float(pose[0]), float(pose[1]), float(pose[2])), kept


def _covariance(
    pose: tuple[float, float, float],
    pixels: NDArray[np.float64],
    points: NDArray[np.float64],
    intrinsics: Intrinsics,
    mount: Mount,
    params: Params,
) -> Covariance:
    jacobian = _jacobian(pose, pixels, points, intrinsics, mount)
    errors = _residuals(pose, pixels, points, intrinsics, mount)
    sigma = max(1.4826 * float(np.median(np.abs(errors))), 0.5)
    try:
        fit = np.linalg.inv(jacobian.T @ jacobian) * sigma**2 * params.inflation
    except np.linalg.LinAlgError:
        return np.diag([1e3, 1e3, 1e3])
    return np.asarray(fit + np.diag(np.square(params.floor)), np.float64)
