"""2D SLAM from a robot's laser scans and odometry: correlative scan matching against the
map being built, occupancy by log-odds, and a pose graph with loop closure.

How it works
============

Every scan comes with the odometry pose of its instant. The odometry step since the last
scan predicts the pose; the scan is matched against a *likelihood field* of the map near
the robot (the points of recent and nearby keyframes, blurred by a Gaussian of the
distance to the nearest one), by an exhaustive search over a small window of positions
and headings, coarse then fine, with bilinear look-ups (the real-time correlative scan
matching of Olson, 2009, as Cartographer and Karto use it). A scan taken after the robot
moved ``keyframe_distance`` or turned ``keyframe_angle`` becomes a keyframe: a node of
the pose graph, tied to the previous keyframe by the matched relative pose.

A new keyframe near an old one (closer than ``loop_radius``, at least ``loop_min_gap``
keyframes earlier) is matched again in a wide window against the old keyframes' points;
a match scoring ``loop_min_score`` adds a loop closure edge with a Huber-robust noise
model, and the graph is optimised by Levenberg-Marquardt. The optimiser is GTSAM's
(``gtsam`` on PyPI, Georgia Tech, maintained and released through 2026): Pose2 factors,
robust noise models and sparse solvers are exactly what a 2D pose graph needs, and
writing them again would be slower and less tried. No well-kept PyPI library does 2D scan
matching and log-odds occupancy (BreezySLAM's last release is from 2018; KISS-ICP and
small_gicp are 3D point cloud registration), so those two are here, in numpy.

The occupancy grid adds each keyframe's scan once, by log-odds (``log_hit`` for the cell
a beam ends in, ``log_miss`` for the cells it crosses, clamped), and is built again from
all keyframes after a loop closure moves them. Cells at or above ``occupied_log_odds``
are occupied, at or below ``free_log_odds`` free, the rest unknown: map_saver's 0.65 and
0.196 thresholds.

Bad readings (NaN, inf, out of ``[range_min, range_max]``) are returns of nothing: they
mark no cell, and scans with too few good beams are not matched. A message whose ranges or
angles are not numbers is refused whole (ValueError).

A session maps within ``max_extent`` metres (either way, in x and in y) of the pose it
started at: the grid grows with the square of the area the robot reports, so one robot's
odometry at (600, 600) m would otherwise cost gigabytes. A scan whose predicted pose falls
outside is refused (``OutsideExtent``, counted in ``MapStats.refused``) and changes
nothing, not even the odometry the next step is measured from.

Nothing here imports Django: the server runs it in a worker thread, tests and benchmarks
on simulated tours.
"""

from __future__ import annotations

import io
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from maps.exceptions import OutsideExtent
from robots.domain.se2 import Pose, compose, inverse, wrap

Floats = npt.NDArray[np.float64]
Grid = npt.NDArray[np.int8]


@dataclass(frozen=True)
class SlamParams:
    """Tuning of the mapper; the defaults suit an LDS-01-class laser indoors."""

    resolution: float = 0.05
    beams_used: int = 120  # beams matched per scan (evenly taken)
    usable_range: float = 7.5  # metres: farther returns are not used
    free_range: float = 4.0  # metres marked free along a beam with no return
    max_extent: float = 50.0  # metres from the start (in x and in y) a session may map
    keyframe_distance: float = 0.25
    keyframe_angle: float = math.radians(12)
    match_every: float = 0.1  # metres (or radians / 4) moved before a scan is matched again
    window_xy: float = 0.15  # metres searched either side of the prediction
    window_yaw: float = math.radians(5)
    sigma: float = 0.05  # metres: the likelihood field's Gaussian
    local_keyframes: int = 40  # recent keyframes the matcher's field is built from
    local_extent: float = 9.0  # metres either side of the robot the field covers
    min_beams: int = 40  # scans with fewer good beams are not matched
    loop_radius: float = 2.5
    loop_min_gap: int = 25  # keyframes between a keyframe and a loop closure partner
    loop_window_xy: float = 0.6
    loop_window_yaw: float = math.radians(15)
    loop_min_score: float = 0.55  # mean likelihood of the beams at the best match
    loop_every: int = 3  # keyframes between loop closure attempts
    log_hit: float = 0.9
    log_miss: float = -0.4
    log_clamp: float = 5.0
    occupied_log_odds: float = math.log(0.65 / 0.35)
    free_log_odds: float = math.log(0.196 / 0.804)
    odom_sigma: tuple[float, float, float] = (0.05, 0.05, math.radians(3))
    match_sigma: tuple[float, float, float] = (0.02, 0.02, math.radians(1))
    loop_sigma: tuple[float, float, float] = (0.05, 0.05, math.radians(2))


@dataclass(frozen=True)
class Scan:
    """A laser scan reduced to what SLAM uses: beam angles (laser frame = robot frame)
    and ranges in metres, NaN where there was no usable return."""

    angles: Floats
    ranges: Floats

    @classmethod
    def from_message(cls, msg: dict[str, object], usable_range: float = math.inf) -> Scan:
        """From a ``sensor_msgs/LaserScan`` in rosbridge JSON (``null`` for no return).

        Raises ValueError for a message with no beams or unusable angle fields."""
        raw = msg.get("ranges")
        if not isinstance(raw, list) or not raw:
            raise ValueError("a scan with no ranges")
        start, step = _number(msg, "angle_min"), _number(msg, "angle_increment")
        low = _number(msg, "range_min", 0.0)
        high = min(_number(msg, "range_max", math.inf), usable_range)
        if not all(r is None or (type(r) in (int, float)) for r in raw):
            raise ValueError("a scan whose ranges are not all numbers (or null)")
        ranges = np.array([math.nan if r is None else r for r in raw], dtype=np.float64)
        ranges[~np.isfinite(ranges) | (ranges < low) | (ranges > high)] = math.nan
        angles = start + step * np.arange(len(ranges), dtype=np.float64)
        if not np.isfinite(angles).all():
            raise ValueError("a scan whose beam angles are not finite")
        return cls(angles, ranges)

    def thinned(self, count: int) -> Scan:
        step = max(1, len(self.ranges) // count)
        return Scan(self.angles[::step], self.ranges[::step])

    def points(self) -> Floats:
        """Returns in the robot frame, shape (n, 2); beams with no return left out."""
        good = np.isfinite(self.ranges)
        r, a = self.ranges[good], self.angles[good]
        return np.column_stack((r * np.cos(a), r * np.sin(a)))


def _number(msg: dict[str, object], key: str, default: float | None = None) -> float:
    value = msg.get(key, default)
    if not isinstance(value, int | float) or not math.isfinite(value):
        if default is not None and value is None:
            return default
        raise ValueError(f"a scan whose {key} is not a number")
    return float(value)


@dataclass
class Keyframe:
    """A node of the pose graph: its pose in the map frame and its scan."""

    pose: Pose
    scan: Scan
    points: Floats  # returns in the robot frame


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


@dataclass
class _Field:
    """A likelihood field: ``values[row, col]`` in [0, 1], cell (0, 0)'s corner at
    ``origin``."""

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
        self._field: _Field | None = None
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

    def _field_near(self, pose: Pose) -> _Field:
        field = self._field
        if field is None or not _covers(field, pose, self.params.local_extent / 2):
            field = self._field = self._local_field(pose)
        return field

    def _local_field(self, centre: Pose) -> _Field:
        recent = self.keyframes[-self.params.local_keyframes :]
        near = [k for k in self.keyframes if _dist(k.pose, centre) < self.params.local_extent]
        chosen = {id(k): k for k in [*near, *recent]}.values()
        world = [_to_map(k.pose, k.points) for k in chosen]
        if self._prior is not None:
            world.append(_occupied_points(*self._prior, self.params.resolution))
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
        points = np.concatenate([_to_map(k.pose, k.points) for k in around])
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


def search(
    field: _Field, points: Floats, guess: Pose, window_xy: float, window_yaw: float, step: float
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


def _best(field: _Field, points: Floats, candidates: Floats) -> tuple[Pose, float]:
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


def likelihood_field(points: Floats, centre: Pose, extent: float, params: SlamParams) -> _Field:
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
    cols = np.floor((points[:, 0] - origin[0]) / res).astype(np.intp)
    rows = np.floor((points[:, 1] - origin[1]) / res).astype(np.intp)
    inside = (rows >= 0) & (rows < size) & (cols >= 0) & (cols < size)
    occupied[rows[inside], cols[inside]] = True
    if not occupied.any():
        return _Field(np.zeros((size, size)), origin, res)
    distance = distance_transform_edt(~occupied) * res
    return _Field(np.exp(-(distance**2) / (2 * params.sigma**2)), origin, res)


def optimise_graph(
    poses: Sequence[Pose], edges: Sequence[tuple[int, int, Pose, tuple[float, float, float], bool]]
) -> list[Pose]:
    """Poses that best agree with ``edges`` ``(i, j, pose of j in i's frame, sigmas,
    robust)``, the first pose held fixed; by GTSAM's Levenberg-Marquardt."""
    import gtsam

    graph = gtsam.NonlinearFactorGraph()
    values = gtsam.Values()
    fixed = gtsam.noiseModel.Diagonal.Sigmas(np.array([1e-4, 1e-4, 1e-5]))
    graph.add(gtsam.PriorFactorPose2(0, gtsam.Pose2(*poses[0]), fixed))
    for index, pose in enumerate(poses):
        values.insert(index, gtsam.Pose2(*pose))
    for i, j, relative, sigmas, robust in edges:
        noise: Any = gtsam.noiseModel.Diagonal.Sigmas(np.array(sigmas))
        if robust:
            huber = gtsam.noiseModel.mEstimator.Huber.Create(1.345)
            noise = gtsam.noiseModel.Robust.Create(huber, noise)
        graph.add(gtsam.BetweenFactorPose2(i, j, gtsam.Pose2(*relative), noise))
    result = gtsam.LevenbergMarquardtOptimizer(graph, values).optimize()
    out: list[Pose] = []
    for index in range(len(poses)):
        found = result.atPose2(index)
        out.append((float(found.x()), float(found.y()), float(found.theta())))
    return out


# --- occupancy -------------------------------------------------------------------------


class LogOddsGrid:
    """A growing log-odds grid; each keyframe's scan is added once (``add``; ``add_view``
    for a scan and its pose), ``grid`` reads it as 100, 0, -1 by the thresholds."""

    CHUNK = 256  # cells the grid grows by at a time, so it is seldom copied

    def __init__(self, params: SlamParams, prior: tuple[Grid, tuple[float, float]] | None) -> None:
        self.params = params
        self.values = np.zeros((0, 0), dtype=np.float32)
        self.origin = (0.0, 0.0)
        if prior is not None:
            grid, origin = prior
            self.origin = origin
            self.values = np.where(
                grid >= 65,
                params.log_clamp / 2,
                np.where((grid >= 0) & (grid < 20), -params.log_clamp / 2, 0.0),
            ).astype(np.float32)

    def add(self, keyframe: Keyframe) -> None:
        p = self.params
        hits = _to_map(keyframe.pose, keyframe.points)
        scan = keyframe.scan
        no_return = ~np.isfinite(scan.ranges)
        reach = np.where(no_return, p.free_range, scan.ranges - p.resolution / 2)
        ends = np.column_stack((np.cos(scan.angles) * reach, np.sin(scan.angles) * reach))
        lengths = np.clip(reach, 0.0, None)
        samples = math.ceil(float(lengths.max(initial=0.0)) / (p.resolution / 2)) + 1
        t = np.linspace(0.0, 1.0, samples)
        along = ends[:, None, :] * t[None, :, None]  # (beams, samples, 2)
        free = _to_map(keyframe.pose, along.reshape(-1, 2))
        self._grow(np.concatenate((hits, free, [keyframe.pose[:2]])))
        free_cells = self._cells(free)
        hit_cells = self._cells(hits)
        free_cells = np.setdiff1d(free_cells, hit_cells)
        flat = self.values.reshape(-1)
        flat[free_cells] += p.log_miss
        flat[hit_cells] += p.log_hit
        np.clip(flat, -p.log_clamp, p.log_clamp, out=flat)

    def add_view(self, pose: Pose, scan: Scan) -> None:
        """Add ``scan`` taken from map-frame ``pose``."""
        self.add(Keyframe(pose, scan, scan.points()))

    def _cells(self, points: Floats) -> npt.NDArray[np.intp]:
        res = self.params.resolution
        cols = np.floor((points[:, 0] - self.origin[0]) / res).astype(np.intp)
        rows = np.floor((points[:, 1] - self.origin[1]) / res).astype(np.intp)
        return np.unique(rows * self.values.shape[1] + cols)

    def _grow(self, points: Floats) -> None:
        """Make the grid hold ``points``, growing it by whole chunks."""
        res = self.params.resolution
        lo, hi = points.min(axis=0), points.max(axis=0)
        height, width = self.values.shape
        x0, y0 = self.origin
        if (
            width
            and lo[0] >= x0
            and lo[1] >= y0
            and hi[0] < x0 + width * res
            and hi[1] < y0 + height * res
        ):
            return
        margin = self.CHUNK // 2 * res
        if not width:
            x0 = math.floor((lo[0] - margin) / res) * res
            y0 = math.floor((lo[1] - margin) / res) * res
            x1, y1 = hi[0] + margin, hi[1] + margin
        else:
            x1, y1 = max(x0 + width * res, hi[0] + margin), max(y0 + height * res, hi[1] + margin)
            x0 = min(x0, x0 - math.ceil((x0 - lo[0] + margin) / res) * res if lo[0] < x0 else x0)
            y0 = min(y0, y0 - math.ceil((y0 - lo[1] + margin) / res) * res if lo[1] < y0 else y0)
        new_w = math.ceil((x1 - x0) / res)
        new_h = math.ceil((y1 - y0) / res)
        grown = np.zeros((new_h, new_w), dtype=np.float32)
        if width:
            c = round((self.origin[0] - x0) / res)
            r = round((self.origin[1] - y0) / res)
            grown[r : r + height, c : c + width] = self.values
        self.values, self.origin = grown, (x0, y0)

    def grid(self) -> tuple[Grid, tuple[float, float]]:
        p = self.params
        out = np.full(self.values.shape, -1, dtype=np.int8)
        out[self.values <= p.free_log_odds] = 0
        out[self.values >= p.occupied_log_odds] = 100
        return out, self.origin


# --- small geometry ----------------------------------------------------------------------


def _to_map(pose: Pose, points: Floats) -> Floats:
    cos, sin = math.cos(pose[2]), math.sin(pose[2])
    x = pose[0] + cos * points[:, 0] - sin * points[:, 1]
    y = pose[1] + sin * points[:, 0] + cos * points[:, 1]
    return np.column_stack((x, y))


def _pose(values: Sequence[float] | Floats) -> Pose:
    return (float(values[0]), float(values[1]), float(values[2]))


def _dist(a: Pose, b: Pose) -> float:
    return math.hypot(a[0] - b[0], a[1] - b[1])


def _covers(field: _Field, pose: Pose, margin: float) -> bool:
    height, width = field.values.shape
    x0, y0 = field.origin
    res = field.resolution
    return bool(
        x0 + margin <= pose[0] <= x0 + width * res - margin
        and y0 + margin <= pose[1] <= y0 + height * res - margin
    )


def _occupied_points(grid: Grid, origin: tuple[float, float], resolution: float) -> Floats:
    rows, cols = np.nonzero(grid >= 65)
    return np.column_stack(
        (origin[0] + (cols + 0.5) * resolution, origin[1] + (rows + 0.5) * resolution)
    )
