"""Visual SLAM of an RGB-D camera on a robot: frame tracking, a keyframe graph, loop
closure and relocalisation, from grey images and registered depth alone (odometry helps
where there is one).

How it works
============

**Tracking** is frame to keyframe with features with depth: each frame's ORB keypoints
(``keyframes.FeatureExtractor``) are matched against the 3D points of the few most
recent keyframes, and the camera's pose is solved as the relocalisation service solves a
wake-up (``relocalisation.relocalise``: the level camera's planar RANSAC, Huber-weighted
refinement, a free 6-DoF check). Tracking against keyframes rather than the previous
frame means standing or creeping adds no drift. It was chosen over OpenCV's dense RGB-D
odometry (``cv2.Odometry``, ``OdometryType_RGB_DEPTH``) by measurement on rendered tours
(``python manage.py bench visual-tracking``; figures in docs/design.md, "Visual SLAM:
tracking").

**Keyframes**: a frame becomes a keyframe (a node of the pose graph) when the camera has
moved ``keyframe_distance`` or turned ``keyframe_angle`` since the keyframe it tracked
against, or when tracking weakens (fewer than ``weak_inliers`` inliers). It is tied to
the newest keyframe it matched by the relative pose tracking measured.

**Loop closure**: each new keyframe's bag of words (``vocabulary``) retrieves older
keyframes (at least ``loop_min_gap`` keyframes earlier); the geometric check solves the
new frame's pose against each candidate's points alone, and a candidate is a loop when
at least ``loop_min_inliers`` matches agree on a pose within ``loop_max_correction``
(plus ``loop_drift`` of the distance travelled since the candidate) of where tracking
puts the camera: two look-alike places farther apart than the drift could explain are
never joined. A loop adds a Huber-robust edge and the graph is optimised by GTSAM
(``slam.optimise_graph``, the laser mapper's); each keyframe's points move rigidly with
its pose, so tracking goes on in the corrected map.

**Lost**: when the recent keyframes do not place a frame (a blank wall, a kidnapped
robot), every keyframe is searched, as a wake-up is (retrieval, then the geometric
check). Until one places it, the pose is dead-reckoned from odometry when there is some
(else held) and the state is ``lost``.

**Restarted**: a robot that loses tracking where the map has nothing (it turned away
from the only view it mapped, its camera was covered) would stay lost for good, since
only a frame some keyframe places goes on. So after ``restart_after_lost`` lost frames
in a row whose pose odometry carried from the last placed frame, mapping starts again
where odometry puts the camera (ORB-SLAM starts a new map on loss; RTAB-Map bridges the
gap with odometry): the frame becomes a keyframe there (state ``restarted``), tied to
the last keyframe tracking used by an odometry edge with wide sigmas
(``restart_sigmas``), so a later loop closure pulls it and what follows into place. A
frame too bare for a keyframe (a covered camera) stays lost and the next one is tried.
Without odometry, or after a frame without it, or on a resumed map before a frame is
placed (nobody counted what the robot did meanwhile), nothing says where the camera
went, so only relocalisation ends the loss.

Nothing here imports Django.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from enum import Enum

import numpy as np

from cloudnav_core.camera import Intrinsics, Mount
from cloudnav_core.se2 import Pose, angle_between, compose, inverse, relative, transform
from maps.domain.keyframes import Depth, FeatureExtractor, Image, Keyframe
from maps.domain.relocalisation import Answer, KeyframeIndex, Params, QueryFrame, relocalise
from maps.domain.slam.pose_graph import optimise_graph
from maps.domain.vocabulary import Vocabulary
from maps.exceptions import KeyframeError

Edge = tuple[int, int, Pose, tuple[float, float, float], bool]


@dataclass(frozen=True)
class VisualSlamParams:
    keyframe_distance: float = 0.3
    keyframe_angle: float = math.radians(15.0)
    weak_inliers: int = 80
    """A frame tracked with fewer inliers than this becomes a keyframe (tracking weakens)."""
    local_keyframes: int = 3
    """Most recent keyframes a frame is tracked against."""
    loop_min_gap: int = 10
    """Keyframes between a new keyframe and a loop closure partner."""
    loop_candidates: int = 3
    """Older keyframes retrieval passes to the geometric check."""
    loop_min_inliers: int = 60
    loop_max_correction: float = 0.5
    """Metres a loop closure may move the camera from where tracking put it, plus..."""
    loop_drift: float = 0.05
    """...this share of the distance travelled since the loop partner was made."""
    tracking_sigmas: tuple[float, float, float] = (0.02, 0.02, math.radians(1.0))
    loop_sigmas: tuple[float, float, float] = (0.03, 0.03, math.radians(1.0))
    restart_after_lost: int = 5
    """Lost frames in a row, each carried by odometry, after which mapping starts again
    from the odometry's pose (a second of a camera at 5 frames/s)."""
    restart_sigmas: tuple[float, float, float] = (0.5, 0.5, math.radians(15.0))
    """The odometry edge that ties a restart to the map: wide, as wheels slip and
    nothing checked them while the camera was lost."""
    solver: Params = field(default_factory=Params)
    """The pose solver's tuning (the relocalisation service's)."""


class State(Enum):
    TRACKING = "tracking"
    RELOCALISED = "relocalised"
    LOST = "lost"
    RESTARTED = "restarted"


@dataclass(frozen=True)
class Tracked:
    """What one frame gave: the robot's ``pose`` (map frame), the ``state``, the
    ``inliers`` that placed it, whether it became a keyframe and closed a loop, and the
    ``reason`` when it was not placed."""

    pose: Pose
    state: State
    inliers: int = 0
    keyframe: bool = False
    loop_closed: bool = False
    reason: str = ""


@dataclass
class _Graph:
    keyframes: list[Keyframe] = field(default_factory=list)
    travelled: list[float] = field(default_factory=list)
    """Metres tracked when each keyframe was made."""
    edges: list[Edge] = field(default_factory=list)
    loops: list[tuple[int, int]] = field(default_factory=list)


class VisualSlam:
    """One camera's map in the making, fed frame by frame with ``track``."""

    def __init__(
        self,
        vocabulary: Vocabulary,
        start: Pose = (0.0, 0.0, 0.0),
        intrinsics: Intrinsics | None = None,
        mount: Mount | None = None,
        params: VisualSlamParams | None = None,
    ) -> None:
        self.extractor = FeatureExtractor(vocabulary)
        self.intrinsics = intrinsics or Intrinsics()
        self.mount = mount or Mount()
        self.params = params or VisualSlamParams()
        self.pose = start
        self.travelled = 0.0
        self._graph = _Graph()
        self._index = KeyframeIndex(vocabulary.size)
        self._odometry: Pose | None = None
        self._lost = False
        self._anchor = 0  # the keyframe the last placed frame was tracked against
        self._bridged: int | None = 0
        """Lost frames in a row whose pose odometry carried from the last placed one; None
        when no odometry carried it from there (a frame without, a resumed map)."""

    @property
    def keyframes(self) -> list[Keyframe]:
        """The keyframes at their current (optimised) poses, oldest first."""
        return list(self._graph.keyframes)

    @property
    def loops(self) -> list[tuple[int, int]]:
        """Loop closures as (older, newer) keyframe positions."""
        return list(self._graph.loops)

    @property
    def edges(self) -> list[Edge]:
        """The graph's edges ``(i, j, pose of j in i's frame, sigmas, loop)``."""
        return list(self._graph.edges)

    @property
    def travelled_at(self) -> list[float]:
        """Metres tracked when each keyframe was made."""
        return list(self._graph.travelled)

    @classmethod
    def resumed(
        cls,
        vocabulary: Vocabulary,
        keyframes: list[Keyframe],
        edges: list[Edge],
        travelled_at: list[float],
        pose: Pose,
        intrinsics: Intrinsics | None = None,
    ) -> VisualSlam:
        """A map holding ``keyframes`` tied by ``edges`` (as a stopped one had them). Its
        first frame is searched against every keyframe, as a wake-up is: the robot may
        have moved while nobody was tracking it."""
        slam = cls(vocabulary, pose, intrinsics)
        slam._graph = _Graph(list(keyframes), list(travelled_at), list(edges), [])
        slam.travelled = max(travelled_at, default=0.0)
        for position, keyframe in enumerate(keyframes):
            slam._index.add(position, "", keyframe)
        slam._lost = bool(keyframes)
        slam._anchor = max(len(keyframes) - 1, 0)
        slam._bridged = None  # the robot may have moved with nobody counting its odometry
        return slam

    def track(self, image: Image, depth: Depth, odometry: Pose | None = None) -> Tracked:
        """Place one frame (grey ``image``, registered ``depth`` in metres, the wheel
        ``odometry`` pose of its instant if any) and grow the map with it.

        Raises KeyframeError when the depth image does not match the image's size."""
        if image.shape[:2] != depth.shape[:2]:
            raise KeyframeError(
                "depth",
                f"the depth image is {depth.shape[1]}x{depth.shape[0]}, "
                f"the colour image {image.shape[1]}x{image.shape[0]}: they must match",
            )
        predicted, carried = self._predicted(odometry)
        pixels, descriptors = self.extractor.detect(image)
        frame = QueryFrame(pixels, descriptors, self.extractor.vocabulary.bag(descriptors))
        if not self._graph.keyframes:
            return self._first(image, depth, predicted)
        answer, state = self._placed(frame)
        if not answer.localised:
            self._bridged = self._bridged + 1 if carried and self._bridged is not None else None
            self._move_to(predicted)
            return self._lost_or_restarted(image, depth, answer)
        self._bridged = 0
        self._anchor = max(answer.keyframes)
        self._move_to(answer.pose)
        made, closed = self._maybe_keyframe(image, depth, frame, answer)
        return Tracked(self.pose, state, answer.inliers, made, closed)

    # --- tracking ---------------------------------------------------------------------

    def _predicted(self, odometry: Pose | None) -> tuple[Pose, bool]:
        """Where the robot is before the image is looked at: the last pose moved by the
        odometry step since the last frame, or the last pose; and whether odometry moved
        it."""
        previous, self._odometry = self._odometry, odometry
        if odometry is None or previous is None:
            return self.pose, False
        return compose(self.pose, relative(previous, odometry)), True

    def _first(self, image: Image, depth: Depth, pose: Pose) -> Tracked:
        try:
            self._add_keyframe(self.extractor.keyframe(image, depth, pose, *self._camera()), None)
        except KeyframeError as error:
            return Tracked(pose, State.LOST, reason=str(error))
        self.pose = pose
        return Tracked(pose, State.TRACKING, len(self._graph.keyframes[0].points), True)

    def _placed(self, frame: QueryFrame) -> tuple[Answer, State]:
        """The frame's pose against the recent keyframes, else (or when the last frame
        was lost: the robot may be anywhere) against all of them."""
        if not self._lost:
            recent = self._local_index()
            answer = relocalise(recent, [frame], *self._camera(), params=self._solver(len(recent)))
            if answer.localised:
                return answer, State.TRACKING
        anywhere = relocalise(self._index, [frame], *self._camera(), params=self.params.solver)
        self._lost = not anywhere.localised
        return anywhere, State.RELOCALISED if anywhere.localised else State.LOST

    def _lost_or_restarted(self, image: Image, depth: Depth, answer: Answer) -> Tracked:
        """A frame no keyframe placed, at the predicted pose: ``lost``, or, once
        ``restart_after_lost`` lost frames in a row were carried by odometry, a keyframe
        tied to the last keyframe tracked by an odometry edge (``restarted``)."""
        if self._bridged is not None and self._bridged >= self.params.restart_after_lost:
            try:
                keyframe = self.extractor.keyframe(image, depth, self.pose, *self._camera())
            except KeyframeError:
                pass  # too bare to map from (a covered camera): the next frame may do
            else:
                self._add_keyframe(keyframe, self._anchor, self.params.restart_sigmas)
                self._lost, self._bridged = False, 0
                return Tracked(self.pose, State.RESTARTED, answer.inliers, keyframe=True)
        return Tracked(self.pose, State.LOST, answer.inliers, reason=answer.reason)

    def _local_index(self) -> KeyframeIndex:
        count = len(self._graph.keyframes)
        local = KeyframeIndex(self.extractor.vocabulary.size)
        for position in range(max(0, count - self.params.local_keyframes), count):
            local.add(position, "", self._graph.keyframes[position])
        return local

    def _solver(self, candidates: int) -> Params:
        return replace(self.params.solver, candidates=candidates)

    def _camera(self) -> tuple[Intrinsics, Mount]:
        return self.intrinsics, self.mount

    def _move_to(self, pose: Pose) -> None:
        self.travelled += math.dist(pose[:2], self.pose[:2])
        self.pose = pose

    # --- keyframes --------------------------------------------------------------------

    def _maybe_keyframe(
        self, image: Image, depth: Depth, frame: QueryFrame, answer: Answer
    ) -> tuple[bool, bool]:
        """Make the frame a keyframe when it is due; whether it did, and closed a loop."""
        anchor = max(answer.keyframes)
        if not self._keyframe_due(self._graph.keyframes[anchor].pose, answer.inliers):
            return False, False
        try:
            keyframe = self.extractor.keyframe(image, depth, self.pose, *self._camera())
        except KeyframeError:
            return False, False
        self._add_keyframe(keyframe, anchor)
        return True, self._close_loop(keyframe, frame)

    def _keyframe_due(self, anchor: Pose, inliers: int) -> bool:
        params = self.params
        return (
            math.dist(anchor[:2], self.pose[:2]) >= params.keyframe_distance
            or angle_between(anchor[2], self.pose[2]) >= params.keyframe_angle
            or inliers < params.weak_inliers
        )

    def _add_keyframe(
        self,
        keyframe: Keyframe,
        anchor: int | None,
        sigmas: tuple[float, float, float] | None = None,
    ) -> None:
        """Add ``keyframe`` tied to keyframe ``anchor`` (if any) by the relative pose of
        the two, with ``sigmas`` (else tracking's)."""
        graph = self._graph
        if anchor is not None:
            measured = relative(graph.keyframes[anchor].pose, keyframe.pose)
            noise = sigmas or self.params.tracking_sigmas
            graph.edges.append((anchor, len(graph.keyframes), measured, noise, False))
        self._anchor = len(graph.keyframes)
        self._index.add(len(graph.keyframes), "", keyframe)
        graph.keyframes.append(keyframe)
        graph.travelled.append(self.travelled)

    # --- loops ------------------------------------------------------------------------

    def _close_loop(self, keyframe: Keyframe, frame: QueryFrame) -> bool:
        """Add a loop closure edge from the newest keyframe to an older one that
        retrieval and the geometric check agree on, and optimise; whether one was."""
        newest = len(self._graph.keyframes) - 1
        for older in self._loop_candidates(keyframe):
            seen = self._seen_from(older, keyframe, frame)
            if seen is not None:
                self._graph.edges.append((older, newest, seen, self.params.loop_sigmas, True))
                self._graph.loops.append((older, newest))
                self._optimise()
                return True
        return False

    def _loop_candidates(self, keyframe: Keyframe) -> list[int]:
        newest = len(self._graph.keyframes) - 1
        wanted = self.params.loop_candidates
        nearest = self._index.nearest(keyframe.words, wanted + self.params.loop_min_gap)
        older = [p for p in nearest if p <= newest - self.params.loop_min_gap]
        return older[:wanted]

    def _seen_from(self, older: int, keyframe: Keyframe, frame: QueryFrame) -> Pose | None:
        """The newest keyframe's pose relative to keyframe ``older`` as the geometric
        check measures it, or None when the check fails."""
        graph = self._graph
        single = KeyframeIndex(self.extractor.vocabulary.size)
        single.add(older, "", graph.keyframes[older])
        answer = relocalise(single, [frame], *self._camera(), params=self._solver(1))
        if not answer.localised or answer.inliers < self.params.loop_min_inliers:
            return None
        since = self.travelled - graph.travelled[older]
        allowed = self.params.loop_max_correction + self.params.loop_drift * since
        if math.dist(answer.pose[:2], keyframe.pose[:2]) > allowed:
            return None
        return relative(graph.keyframes[older].pose, answer.pose)

    def _optimise(self) -> None:
        """Optimise the graph; move every keyframe (and the camera) with its node."""
        graph = self._graph
        before = [k.pose for k in graph.keyframes]
        after = optimise_graph(before, graph.edges)
        graph.keyframes = [_moved(k, p) for k, p in zip(graph.keyframes, after, strict=True)]
        self.pose = compose(after[-1], relative(before[-1], self.pose))
        self._index = KeyframeIndex(self.extractor.vocabulary.size)
        for position, keyframe in enumerate(graph.keyframes):
            self._index.add(position, "", keyframe)


def _moved(keyframe: Keyframe, pose: Pose) -> Keyframe:
    """``keyframe`` at ``pose``, its points carried rigidly with it."""
    correction = compose(pose, inverse(keyframe.pose))
    points = keyframe.points.copy()
    points[:, :2] = transform(correction, keyframe.points[:, :2].astype(np.float64))
    return Keyframe(pose, keyframe.descriptors, points, keyframe.words)
