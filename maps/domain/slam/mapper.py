"""``Mapper``: one map built from a stream of ``(odometry pose, scan)``, with what it did
(``MapStats``) and its state saved and resumed as bytes.

Every scan comes with the odometry pose of its instant. The odometry step since the last
scan predicts the pose; the scan is matched against the likelihood field of the map near
the robot (``matching``). A scan taken after the robot moved ``keyframe_distance`` or
turned ``keyframe_angle`` becomes a keyframe: a node of the pose graph, tied to the
previous keyframe by the matched relative pose.

A new keyframe near an old one (closer than ``loop_radius``, at least ``loop_min_gap``
keyframes earlier) is matched again in a wide window against the old keyframes' points;
a match scoring ``loop_min_score`` adds a loop closure edge with a Huber-robust noise
model, and the graph is optimised (``pose_graph``). The occupancy grid (``occupancy``) is
built again from all keyframes after a loop closure moves them.

A session maps within ``max_extent`` metres (either way, in x and in y) of the pose it
started at: the grid grows with the square of the area the robot reports, so one robot's
odometry at (600, 600) m would otherwise cost gigabytes. A scan whose predicted pose falls
outside is refused (``OutsideExtent``, counted in ``MapStats.refused``) and changes
nothing, not even the odometry the next step is measured from.
"""

from __future__ import annotations

import io
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from cloudnav_core.se2 import Floats, Pose, compose, inverse, transform, wrap
from maps.exceptions import OutsideExtent

from .matching import Field, likelihood_field, search
from .occupancy import Grid, LogOddsGrid, occupied_points
from .params import SlamParams
from .pose_graph import optimise_graph
from .scans import Keyframe, Scan


@dataclass
class MapStats:
    """What the mapper did, for the session's page and the benchmark."""

    scans: int = 0
    matched: int = 0
    skipped: int = 0  # scans with too few good beams
    refused: int = 0  # scans at a pose outside the session's extent
    keyframes: int = 0
    loop_closures: int = 0
    optimisations: int = 0


class Mapper:
    """Builds one map from a stream of ``(odometry pose, scan)``.

    ``start`` is the map-frame pose of the first scan (a new sub-map shares the building's
    frame when it is the robot's pose estimate there). ``prior`` (a grid with its origin)
    seeds the map when a stored sub-map is brought up to date: it is matched against from
    the first scan and shows through where the robot has not looked yet.
    """

    def __init__(
        self,
        params: SlamParams | None = None,
        start: Pose = (0.0, 0.0, 0.0),
        prior: tuple[Grid, tuple[float, float]] | None = None,
    ) -> None:
        self.params = params or SlamParams()
        self.keyframes: list[Keyframe] = []
        self.stats = MapStats()
        self.pose: Pose = start
        self.anchor: Pose = start  # the extent is measured from here
        self.path: list[Pose] = []  # corrected pose of every matched scan
        self._odom: Pose | None = None
        self._matched_odom: Pose | None = None
        self._field: Field | None = None
        self._prior = prior
        self._log_odds: LogOddsGrid | None = LogOddsGrid(self.params, prior)
        self._edges: list[tuple[int, int, Pose, tuple[float, float, float], bool]] = []
        self._last_loop_try = 0
        self._resuming = False

    # --- the stream ---------------------------------------------------------------------

    def add(self, odom: Pose, scan: Scan) -> Pose:
        """Take one scan with the odometry pose of its instant; returns the corrected pose.

        Raises OutsideExtent (and keeps everything as it was) when the odometry puts the
        robot beyond ``max_extent`` of where the session started."""
        self.stats.scans += 1
        predicted = self.pose
        if self._odom is not None:
            predicted = compose(self.pose, compose(inverse(self._odom), odom))
        self._refuse_outside(predicted)
        self.pose, self._odom = predicted, odom
        if not self._moved_enough(odom):
            return self.pose
        thin = scan.thinned(self.params.beams_used)
        points = thin.points()
        points = points[np.hypot(points[:, 0], points[:, 1]) <= self.params.usable_range]
        if len(points) < self.params.min_beams:
            self.stats.skipped += 1
            return self.pose
        if self.keyframes or self._prior is not None:
            self.pose = self._match(points, self.pose)
        self._matched_odom = odom
        self.stats.matched += 1
        self.path.append(self.pose)
        if self._is_keyframe():
            self._add_keyframe(Keyframe(self.pose, thin, points))
        return self.pose

    def _refuse_outside(self, pose: Pose) -> None:
        limit = self.params.max_extent
        away = max(abs(pose[0] - self.anchor[0]), abs(pose[1] - self.anchor[1]))
        if not away <= limit or not math.isfinite(pose[2]):  # NaN too
            self.stats.refused += 1
            raise OutsideExtent(
                f"the robot reports a pose at ({pose[0]:.1f}, {pose[1]:.1f}), {away:.0f} m "
                f"from where the session started: a session maps within {limit:g} m of it"
            )

    def _moved_enough(self, odom: Pose) -> bool:
        last = self._matched_odom
        if last is None:
            return True
        step = compose(inverse(last), odom)
        return math.hypot(step[0], step[1]) + abs(wrap(step[2])) / 4 >= self.params.match_every

    def _is_keyframe(self) -> bool:
        if not self.keyframes:
            return True
        step = compose(inverse(self.keyframes[-1].pose), self.pose)
        far = math.hypot(step[0], step[1]) >= self.params.keyframe_distance
        return far or abs(wrap(step[2])) >= self.params.keyframe_angle

    # --- scan matching ----------------------------------------------------------------

    def _match(self, points: Floats, guess: Pose) -> Pose:
        field = self._field_near(guess)
        p = self.params
        if self._resuming:
            self._resuming = False
            best, _ = search(field, points, guess, p.loop_window_xy, p.loop_window_yaw, 0.1)
            return best
        best, _ = search(field, points, guess, p.window_xy, p.window_yaw, p.resolution)
        return best

    def _field_near(self, pose: Pose) -> Field:
        field = self._field
        if field is None or not _covers(field, pose, self.params.local_extent / 2):
            field = self._field = self._local_field(pose)
        return field

    def _local_field(self, centre: Pose) -> Field:
        recent = self.keyframes[-self.params.local_keyframes :]
        near = [k for k in self.keyframes if _dist(k.pose, centre) < self.params.local_extent]
        chosen = {id(k): k for k in [*near, *recent]}.values()
        world = [transform(k.pose, k.points) for k in chosen]
        if self._prior is not None:
            world.append(occupied_points(*self._prior, self.params.resolution))
        points = np.concatenate(world) if world else np.zeros((0, 2))
        return likelihood_field(points, centre, self.params.local_extent, self.params)

    # --- the graph -----------------------------------------------------------------------

    def _add_keyframe(self, keyframe: Keyframe) -> None:
        index = len(self.keyframes)
        if index:
            previous = self.keyframes[-1]
            step = compose(inverse(previous.pose), keyframe.pose)
            self._edges.append((index - 1, index, step, self.params.match_sigma, False))
        self.keyframes.append(keyframe)
        self.stats.keyframes += 1
        if self._log_odds is not None:
            self._log_odds.add(keyframe)
        self._field = None  # rebuilt with this keyframe at the next match
        if index - self._last_loop_try >= self.params.loop_every:
            self._last_loop_try = index
            if self._close_loop(index):
                self._optimise()

    def _close_loop(self, index: int) -> bool:
        """Try to match keyframe ``index`` against an old keyframe near it."""
        p = self.params
        new = self.keyframes[index]
        old = [
            j
            for j in range(0, index - p.loop_min_gap)
            if _dist(self.keyframes[j].pose, new.pose) < p.loop_radius
        ]
        if not old:
            return False
        anchor = min(old, key=lambda j: _dist(self.keyframes[j].pose, new.pose))
        around = self.keyframes[max(0, anchor - 5) : anchor + 6]
        points = np.concatenate([transform(k.pose, k.points) for k in around])
        field = likelihood_field(points, new.pose, p.loop_radius + p.usable_range, p)
        pose, score = search(field, new.points, new.pose, p.loop_window_xy, p.loop_window_yaw, 0.1)
        if score < p.loop_min_score:
            return False
        relative = compose(inverse(self.keyframes[anchor].pose), pose)
        self._edges.append((anchor, index, relative, p.loop_sigma, True))
        self.stats.loop_closures += 1
        return True

    def _optimise(self) -> None:
        """Optimise the pose graph (GTSAM, Levenberg-Marquardt) and move the keyframes."""
        poses = optimise_graph([k.pose for k in self.keyframes], self._edges)
        shift = compose(poses[-1], inverse(self.keyframes[-1].pose))
        for keyframe, pose in zip(self.keyframes, poses, strict=True):
            keyframe.pose = pose
        self.pose = compose(shift, self.pose)
        self.path = [compose(shift, p) for p in self.path]
        self._log_odds = None  # built again from the moved keyframes when next asked for
        self._field = None
        self.stats.optimisations += 1

    # --- the map ---------------------------------------------------------------------

    def grid(self) -> tuple[Grid, tuple[float, float]]:
        """The occupancy grid so far (row 0 = bottom; 100, 0, -1) and the map-frame
        position of its cell (0, 0)'s corner."""
        if self._log_odds is None:
            self._log_odds = LogOddsGrid(self.params, self._prior)
            for keyframe in self.keyframes:
                self._log_odds.add(keyframe)
        return self._log_odds.grid()

    def keyframe_poses(self) -> list[Pose]:
        return [k.pose for k in self.keyframes]

    # --- resuming ---------------------------------------------------------------------

    def state(self) -> bytes:
        """The keyframes and the graph's edges as ``.npz`` bytes (no pickle), so a session
        can be resumed by ``Mapper.resumed`` in another process."""
        out = io.BytesIO()
        beams = max((len(k.scan.ranges) for k in self.keyframes), default=0)
        ranges = np.full((len(self.keyframes), beams), np.nan)
        angles = np.full((len(self.keyframes), beams), np.nan)
        for index, keyframe in enumerate(self.keyframes):
            ranges[index, : len(keyframe.scan.ranges)] = keyframe.scan.ranges
            angles[index, : len(keyframe.scan.angles)] = keyframe.scan.angles
        edges = np.array(
            [(i, j, *rel, *sig, float(robust)) for i, j, rel, sig, robust in self._edges]
        )
        np.savez_compressed(
            out,
            poses=np.array([k.pose for k in self.keyframes]).reshape(-1, 3),
            ranges=ranges,
            angles=angles,
            edges=edges.reshape(-1, 9),
            pose=np.array(self.pose),
            anchor=np.array(self.anchor),
            path=np.array(self.path).reshape(-1, 3),
        )
        return out.getvalue()

    @classmethod
    def resumed(
        cls,
        data: bytes,
        params: SlamParams | None = None,
        prior: tuple[Grid, tuple[float, float]] | None = None,
    ) -> Mapper:
        """A mapper holding the keyframes ``state`` saved; its first scan is matched in
        the loop closure window, as the robot may have moved while it was away.

        Raises ValueError for bytes ``state`` did not make."""
        try:
            saved = np.load(io.BytesIO(data), allow_pickle=False)
            mapper = cls(params, _pose(saved["pose"]), prior)
            for pose, ranges, angles in zip(
                saved["poses"], saved["ranges"], saved["angles"], strict=True
            ):
                good = ~np.isnan(angles)
                scan = Scan(angles[good], ranges[good])
                mapper.keyframes.append(Keyframe(_pose(pose), scan, scan.points()))
            for row in saved["edges"]:
                mapper._edges.append(
                    (int(row[0]), int(row[1]), _pose(row[2:5]), _pose(row[5:8]), bool(row[8]))
                )
            mapper.path = [_pose(p) for p in saved["path"]]
            if "anchor" in saved.files:  # states saved before the extent had none
                mapper.anchor = _pose(saved["anchor"])
        except (OSError, KeyError, ValueError, TypeError) as error:
            raise ValueError(f"not a saved mapping state: {error}") from None
        mapper.stats.keyframes = len(mapper.keyframes)
        mapper._log_odds = None
        mapper._resuming = True
        return mapper


def _pose(values: Sequence[float] | Floats) -> Pose:
    return (float(values[0]), float(values[1]), float(values[2]))


def _dist(a: Pose, b: Pose) -> float:
    return math.hypot(a[0] - b[0], a[1] - b[1])


def _covers(field: Field, pose: Pose, margin: float) -> bool:
    height, width = field.values.shape
    x0, y0 = field.origin
    res = field.resolution
    return bool(
        x0 + margin <= pose[0] <= x0 + width * res - margin
        and y0 + margin <= pose[1] <= y0 + height * res - margin
    )
