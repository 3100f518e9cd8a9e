"""The timed elastic band (TEB) local planner (Rösmann et al., 2012, 2017), as the
second source system drives with it.

A band is a sequence of poses ``(x, y, yaw)`` with the time interval between each two.
Each control cycle:

1. The band is initialised from the global path ahead (``horizon`` metres of it, in the
   robot's frame), or the last cycle's band is carried into the robot's new frame and
   its start and goal are moved to the robot and to the path's new local goal.
2. Poses are added or removed so that every interval stays near ``dt_ref`` (within
   ``dt_hysteresis``): the band grows and shrinks with the horizon and the speed.
3. The band is optimised over a weighted sum of squared objectives: via-points along the
   path, clearance from what the laser sees (each return predicted at constant velocity
   to the time the band passes it, ``robots.agent.tracking``), velocity and acceleration
   limits, the differential-drive (non-holonomic) kinematics, driving forwards, and the
   total time. That is a sparse nonlinear least-squares problem (each term depends on
   at most three neighbouring poses and two intervals), solved by SciPy's
   ``least_squares`` (trust-region reflective) with the Jacobian's sparsity given, so
   that finite differences need one evaluation per group of independent columns (about
   ten) rather than per variable, and the intervals kept positive by bounds. This
   replaces the g2o graph optimiser of the original: the same Levenberg-Marquardt-like
   step on the same sparse structure, from a well-kept library with no build step.
   Obstacle times are fixed at the start of each cycle, as the original does.
4. The optimised band is checked against the hard constraint over its first
   ``feasibility_time`` seconds: clearance of at least the body's radius from every
   predicted return, at its poses and midway between them. A band that runs into
   something anywhere is also rebuilt from the path and bent either way round it, each
   optimised, and the best kept; if none is feasible, or every one runs into something
   standing still (a wall across the way), the robot stops (and the driver plans the
   global path again around what it sees, as it does for a blocked DWA).
5. The command is the first interval's velocity, clamped to what the body can reach
   within one period.

Left out from the original: exploring several homotopy classes in parallel (a band that
cannot pass an obstacle on one side relies on the driver's global replanning), and
car-like kinematics.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import least_squares

from robots.agent.tracking import ObstacleTracker, SeenObstacles
from robots.domain.params import RobotConfig, TebConfig
from robots.domain.se2 import Point, Pose, inverse, transform, wrap

Floats = NDArray[np.float64]
Command = tuple[float, float]

OBSTACLE_REACH = 1.0
"""Metres from the band beyond which laser returns are left out of its optimisation."""
LSMR_ITERATIONS = 12
"""Iterations of the inner least-squares solver per step: an approximate step is enough
when the band is warm-started each cycle, and it bounds the cycle's time."""
MIN_DT = 0.02
"""Seconds: the least time interval between two poses of a band."""


@dataclass
class Band:
    """Poses ``(n + 1, 3)`` and the ``n`` time intervals between them, in one frame."""

    poses: Floats
    dts: Floats

    @property
    def times(self) -> Floats:
        """Seconds from the band's start to each pose."""
        return np.concatenate([[0.0], np.cumsum(self.dts)])

    def velocities(self) -> tuple[Floats, Floats]:
        """Linear (signed: negative backwards) and angular velocity of each interval."""
        return _velocities(self.poses, self.dts)

    def moved(self, frame: Pose) -> Band:
        """This band seen from ``frame`` (a pose in the band's current frame)."""
        xy = transform(inverse(frame), self.poses[:, :2])
        yaw = wrap(self.poses[:, 2] - frame[2])
        return Band(np.column_stack([xy, yaw]), self.dts.copy())


# --- building the band -------------------------------------------------------------------


def band_from_path(path: Floats, goal_yaw: float, config: RobotConfig) -> Band:
    """A band along ``path`` (robot frame, starting at the robot) with poses about
    ``dt_ref`` apart at cruising speed, headings along the path and ``goal_yaw`` at its
    end, each interval as long as driving it at top speed takes (turns included)."""
    spacing = config.teb.dt_ref * config.body.max_linear
    points = _resampled(path, spacing)
    yaw = np.arctan2(np.diff(points[:, 1]), np.diff(points[:, 0]))
    yaw = (
        np.concatenate([[0.0], yaw[1:], [goal_yaw]])
        if len(points) > 2
        else np.array([0.0, goal_yaw])
    )
    poses = np.column_stack([points, yaw])
    return Band(poses, _least_times(poses, config))


def _resampled(path: Floats, spacing: float) -> Floats:
    """Points every ``spacing`` metres along the polyline ``path`` (its ends kept)."""
    steps = np.hypot(*np.diff(path, axis=0).T)
    along = np.concatenate([[0.0], np.cumsum(steps)])
    count = max(math.ceil(float(along[-1]) / spacing), 1)
    wanted = np.linspace(0.0, along[-1], count + 1)
    return np.column_stack(
        [np.interp(wanted, along, path[:, 0]), np.interp(wanted, along, path[:, 1])]
    )


def _least_times(poses: Floats, config: RobotConfig) -> Floats:
    """The time each interval takes at top linear and angular speed."""
    body = config.body
    distance = np.hypot(*np.diff(poses[:, :2], axis=0).T)
    turn = np.abs(wrap(np.diff(poses[:, 2])))
    least = np.maximum(distance / body.max_linear, turn / body.max_angular)
    return np.asarray(np.maximum(least, MIN_DT), np.float64)


def resized(band: Band, config: TebConfig) -> Band:
    """Poses inserted where an interval exceeds ``dt_ref + dt_hysteresis`` and removed
    where one falls below ``dt_ref - dt_hysteresis``, keeping between ``min_poses`` and
    ``max_poses`` (TEB's ``autoResize``)."""
    poses, dts = list(band.poses), list(band.dts)
    index = 0
    while index < len(dts):
        if dts[index] > config.dt_ref + config.dt_hysteresis and len(poses) < config.max_poses:
            poses.insert(index + 1, _midpose(poses[index], poses[index + 1]))
            half = dts[index] / 2
            dts[index : index + 1] = [half, half]
            continue
        last = index == len(dts) - 1
        if (
            dts[index] < config.dt_ref - config.dt_hysteresis
            and not last
            and len(poses) > config.min_poses
        ):
            dts[index : index + 2] = [dts[index] + dts[index + 1]]
            del poses[index + 1]
            continue
        index += 1
    return Band(np.array(poses), np.array(dts))


def _midpose(a: Floats, b: Floats) -> Floats:
    return np.array([(a[0] + b[0]) / 2, (a[1] + b[1]) / 2, a[2] + wrap(b[2] - a[2]) / 2])


# --- the objectives ----------------------------------------------------------------------


def _velocities(poses: Floats, dts: Floats) -> tuple[Floats, Floats]:
    delta = np.diff(poses[:, :2], axis=0)
    heading = poses[:-1, 2]
    forward = delta[:, 0] * np.cos(heading) + delta[:, 1] * np.sin(heading)
    sign = np.where(forward >= 0, 1.0, -1.0)
    linear = sign * np.hypot(delta[:, 0], delta[:, 1]) / dts
    angular = wrap(np.diff(poses[:, 2])) / dts
    return linear, angular


class _Problem:
    """One cycle's optimisation: the fixed start and goal, the start velocity, the
    obstacles predicted at each probe's time (``(probes, k, 2)``, see ``_probes``), the
    via-points and the inner pose each pulls, and whether the goal is the target itself
    (to be reached at rest).

    Variables ``x``: the inner poses' ``(x, y, yaw)`` then the ``n`` intervals (as
    ``pack`` writes them). Rows of
    the residuals and of the Jacobian (both exact, computed together): kinematics,
    driving backwards, linear and angular speed beyond the limits (``n`` each), linear
    and angular acceleration beyond the limits (``n + 1`` each), time (``n``), clearance
    and inflation (one per probe), via-points (x and y each).
    """

    def __init__(
        self,
        start: Floats,
        goal: Floats,
        velocity: Command,
        obstacles: Floats,
        vias: Floats,
        via_poses: NDArray[np.intp],
        config: RobotConfig,
        final: bool,
    ) -> None:
        self.start, self.goal, self.velocity = start, goal, velocity
        self.obstacles, self.vias, self.via_poses = obstacles, vias, via_poses
        self.config, self.final = config, final
        self.inner = int(obstacles.shape[0]) // 2  # probes: inner poses and midpoints
        self._at: Floats | None = None
        self._cached: tuple[Floats, Floats] = (np.zeros(0), np.zeros((0, 0)))

    def pack(self, band: Band) -> Floats:
        """The variables of ``band``: its inner poses, then each interval as the log of
        its excess over ``MIN_DT`` (so that no step of the optimiser makes one shorter)."""
        excess = np.maximum(band.dts - MIN_DT, 1e-6)
        return np.concatenate([band.poses[1:-1].ravel(), np.log(excess)])

    def unpack(self, x: Floats) -> tuple[Floats, Floats]:
        m = self.inner
        poses = np.vstack([self.start, x[: 3 * m].reshape(m, 3), self.goal])
        return poses, MIN_DT + np.exp(x[3 * m :])

    def residuals(self, x: Floats) -> Floats:
        return self._evaluate(x)[0]

    def jacobian(self, x: Floats) -> Floats:
        return self._evaluate(x)[1]

    def _evaluate(self, x: Floats) -> tuple[Floats, Floats]:
        if self._at is None or not np.array_equal(self._at, x):
            residuals, jacobian = _Terms(self, x).stacked()
            m = self.inner
            jacobian[:, 3 * m :] *= np.exp(x[3 * m :])  # d(dt)/d(variable)
            self._at, self._cached = x.copy(), (residuals, jacobian)
        return self._cached


def _probes(inner: int) -> tuple[NDArray[np.intp], NDArray[np.intp], Floats]:
    """Where a band of ``inner`` inner poses is checked for clearance: pose indices
    ``first`` and ``second`` and the ``share`` of the first (the inner poses, then the
    midpoints of the ``inner + 1`` intervals)."""
    poses, intervals = np.arange(1, inner + 1), np.arange(inner + 1)
    first = np.concatenate([poses, intervals])
    second = np.concatenate([poses, intervals + 1])
    return first, second, np.concatenate([np.ones(inner), np.full(inner + 1, 0.5)])


class _Terms:
    """The residuals and Jacobian of one ``_Problem`` at one ``x``, built term by term."""

    def __init__(self, problem: _Problem, x: Floats) -> None:
        self.problem, self.teb, self.body = problem, problem.config.teb, problem.config.body
        self.poses, self.dts = problem.unpack(x)
        self.m, self.n = problem.inner, problem.inner + 1
        self.rows: list[Floats] = []
        self.jacobians: list[Floats] = []
        delta = np.diff(self.poses[:, :2], axis=0)
        self.dx, self.dy = delta[:, 0], delta[:, 1]
        self.dist = np.maximum(np.hypot(self.dx, self.dy), 1e-9)
        self.c, self.s = np.cos(self.poses[:, 2]), np.sin(self.poses[:, 2])
        self.forward = self.dx * self.c[:-1] + self.dy * self.s[:-1]
        self.sign = np.where(self.forward >= 0, 1.0, -1.0)
        self.linear = self.sign * self.dist / self.dts
        self.angular = wrap(np.diff(self.poses[:, 2])) / self.dts

    def stacked(self) -> tuple[Floats, Floats]:
        teb, body = self.teb, self.body
        self._kinematics(teb.weight_kinematics)
        self._backwards(teb.weight_forward)
        self._speed_limits(teb.weight_velocity, body.max_linear, body.max_angular)
        self._acceleration_limits(teb.weight_acceleration, body.linear_accel, body.angular_accel)
        self._time(teb.weight_time)
        keep_off = body.radius + teb.min_obstacle_dist
        self._clearance([(teb.weight_obstacle, keep_off), (teb.weight_inflation, teb.inflation)])
        self._vias(teb.weight_viapoint)
        return np.concatenate(self.rows), np.vstack(self.jacobians)

    # --- bookkeeping ---

    def _block(self, count: int) -> Floats:
        return np.zeros((count, 3 * self.m + self.n))

    def _add(self, weight: float, values: Floats, jacobian: Floats) -> None:
        root = math.sqrt(weight)
        self.rows.append(root * values)
        self.jacobians.append(root * jacobian)

    def _put(
        self,
        jac: Floats,
        rows: NDArray[np.intp],
        pose: NDArray[np.intp],
        values: Floats,
        part: int = 0,
    ) -> None:
        """Add ``values`` (one row of k per entry of ``rows``) at ``rows`` to the columns
        of components ``part`` to ``part + k - 1`` (0 x, 1 y, 2 yaw) of each ``pose``
        (0..n; the fixed start and goal have none)."""
        free = (pose > 0) & (pose < self.n)
        columns = 3 * (pose[free] - 1)[:, None] + part + np.arange(values.shape[1])
        jac[rows[free][:, None], columns] += values[free]

    def _put_dt(
        self, jac: Floats, rows: NDArray[np.intp], interval: NDArray[np.intp], values: Floats
    ) -> None:
        valid = (interval >= 0) & (interval < self.n)
        jac[rows[valid], 3 * self.m + interval[valid]] += values[valid]

    def _segment_derivative(
        self,
        jac: Floats,
        rows: NDArray[np.intp],
        segment: NDArray[np.intp],
        scale: Floats,
        which: str,
    ) -> None:
        """Add ``scale`` times the derivative of segment ``segment``'s linear or angular
        velocity (``which``) to ``rows``."""
        i = segment
        if which == "linear":
            factor = scale * self.sign[i] / (self.dist[i] * self.dts[i])
            step = factor[:, None] * np.column_stack([self.dx[i], self.dy[i]])
            self._put(jac, rows, i, -step)
            self._put(jac, rows, i + 1, step)
            self._put_dt(jac, rows, i, -scale * self.linear[i] / self.dts[i])
        else:
            turn = (scale / self.dts[i])[:, None]
            self._put(jac, rows, i, -turn, part=2)
            self._put(jac, rows, i + 1, turn, part=2)
            self._put_dt(jac, rows, i, -scale * self.angular[i] / self.dts[i])

    # --- the objectives ---

    def _kinematics(self, weight: float) -> None:
        """Non-holonomic: both headings make the same angle with the step between them."""
        c, s, i = self.c, self.s, np.arange(self.n)
        cc, ss = c[:-1] + c[1:], s[:-1] + s[1:]
        values = cc * self.dy - ss * self.dx
        jac = self._block(self.n)
        self._put(jac, i, i, np.column_stack([ss, -cc, -s[:-1] * self.dy - c[:-1] * self.dx]))
        self._put(jac, i, i + 1, np.column_stack([-ss, cc, -s[1:] * self.dy - c[1:] * self.dx]))
        self._add(weight, values, jac)

    def _backwards(self, weight: float) -> None:
        i, active = np.arange(self.n), (self.forward < 0).astype(np.float64)
        c, s = self.c[:-1], self.s[:-1]
        jac = self._block(self.n)
        heading = np.column_stack([c, s, self.dx * s - self.dy * c])
        self._put(jac, i, i, active[:, None] * heading)
        self._put(jac, i, i + 1, -active[:, None] * heading[:, :2])
        self._add(weight, np.maximum(-self.forward, 0.0), jac)

    def _speed_limits(self, weight: float, max_linear: float, max_angular: float) -> None:
        i = np.arange(self.n)
        for which, speed, limit in (
            ("linear", self.linear, max_linear),
            ("angular", self.angular, max_angular),
        ):
            excess = np.abs(speed) - limit
            jac = self._block(self.n)
            self._segment_derivative(jac, i, i, np.where(excess > 0, np.sign(speed), 0.0), which)
            self._add(weight, np.maximum(excess, 0.0), jac)

    def _acceleration_limits(self, weight: float, max_linear: float, max_angular: float) -> None:
        """Between the start velocity and the first interval, each two intervals, and
        (for the final goal) the last interval and rest."""
        n, dts, final = self.n, self.dts, self.problem.final
        spans = np.concatenate([[dts[0]], (dts[:-1] + dts[1:]) / 2, [dts[-1]]])
        k = np.arange(n + 1)
        for part, speed, limit in ((0, self.linear, max_linear), (1, self.angular, max_angular)):
            end = 0.0 if final else speed[-1]
            v = np.concatenate([[self.problem.velocity[part]], speed, [end]])
            accel = np.diff(v) / spans
            excess = np.abs(accel) - limit
            scale = (excess > 0) * np.sign(accel) / spans
            if not final:
                scale[-1] = 0.0  # the last interval's velocity to itself: no term
            jac = self._block(n + 1)
            which = "linear" if part == 0 else "angular"
            self._segment_derivative(jac, k[:-1], k[:-1], scale[:-1], which)
            self._segment_derivative(jac, k[1:], k[1:] - 1, -scale[1:], which)
            # The span's own derivative: each row's a/span times d(span)/d(dt).
            factor = -scale * accel
            self._put_dt(jac, k[:1], k[:1], factor[:1])
            self._put_dt(jac, k[1:-1], k[1:-1] - 1, 0.5 * factor[1:-1])
            self._put_dt(jac, k[1:-1], k[1:-1], 0.5 * factor[1:-1])
            self._put_dt(jac, k[-1:], k[-1:] - 1, factor[-1:])
            self._add(weight, np.maximum(excess, 0.0), jac)

    def _time(self, weight: float) -> None:
        i = np.arange(self.n)
        jac = self._block(self.n)
        self._put_dt(jac, i, i, np.ones(self.n))
        self._add(weight, self.dts.copy(), jac)

    def _clearance(self, hinges: list[tuple[float, float]]) -> None:
        """Per probe (each inner pose, then each interval's midpoint, so that no obstacle
        slips between two poses), how far inside each of ``hinges`` (weight, distance)
        the nearest return predicted for its time lies."""
        first, second, share = _probes(self.m)
        probes = (
            share[:, None] * self.poses[first, :2] + (1 - share)[:, None] * self.poses[second, :2]
        )
        obstacles, count = self.problem.obstacles, len(first)
        rows = np.arange(count)
        if obstacles.shape[1] == 0:
            distance, away = np.full(count, np.inf), np.zeros((count, 2))
        else:
            gap = probes[:, None, :] - obstacles
            squared = (gap**2).sum(axis=2)
            closest = np.argmin(squared, axis=1)
            distance = np.sqrt(squared[rows, closest])
            away = gap[rows, closest] / np.maximum(distance, 1e-9)[:, None]
        for weight, reach in hinges:
            active = (distance < reach).astype(np.float64)
            jac = self._block(count)
            for pose, part in ((first, share), (second, 1 - share)):
                self._put(jac, rows, pose, -(active * part)[:, None] * away)
            self._add(weight, np.maximum(reach - distance, 0.0), jac)

    def _vias(self, weight: float) -> None:
        pulled = self.problem.via_poses
        count = len(pulled)
        values = (self.poses[1:-1][pulled, :2] - self.problem.vias).ravel()
        jac = self._block(2 * count)
        rows = np.arange(2 * count)
        self._put(jac, rows[0::2], pulled + 1, np.ones((count, 1)))
        self._put(jac, rows[1::2], pulled + 1, np.ones((count, 1)), part=1)
        self._add(weight, values, jac)


# --- the controller ----------------------------------------------------------------------


@dataclass(frozen=True)
class TebChoice:
    """The command, whether the robot had to stop for want of a feasible band, and the
    band that gave it (robot frame)."""

    command: Command
    blocked: bool
    band: Band | None


class TimedElasticBand:
    """The TEB local planner of one robot; keeps its band and obstacle tracks between
    cycles (``choose`` once per control period)."""

    def __init__(self, config: RobotConfig) -> None:
        self.config = config
        self.tracker = ObstacleTracker()
        self.band: Band | None = None  # the last band, odometry frame

    def reset(self) -> None:
        self.band = None

    def choose(
        self,
        path: Floats,
        goal_yaw: float,
        final: bool,
        velocity: Command,
        points: Floats,
        odom: Pose,
        seconds: float,
        speed_cap: float = math.inf,
    ) -> TebChoice:
        """The command along ``path`` (robot frame, from the robot to the local goal,
        whose heading is ``goal_yaw``; ``final`` when it is the target itself) from
        ``velocity``, around the laser returns ``points`` (robot frame) seen at
        ``seconds`` with the odometry at ``odom``."""
        seen = self.tracker.update(points, odom, seconds)
        solved = [
            self._optimised(self._warm_band(path, goal_yaw, odom), path, velocity, seen, final)
        ]
        if not feasible(solved[0][0], seen, self.config, math.inf):
            # Something in the band's way: replan it, from the path and swerving either
            # way round the first thing it meets (two homotopy classes of the original's
            # many), and keep the best: feasible now, clear all along, cheapest.
            fresh = band_from_path(path, goal_yaw, self.config)
            tries = [fresh, *(_swerved(fresh, seen, side, self.config) for side in (1.0, -1.0))]
            solved += [self._optimised(start, path, velocity, seen, final) for start in tries]
        ranked = sorted(solved, key=lambda found: self._rank(found, seen))
        band = ranked[0][0]
        if not feasible(band, seen, self.config) or _walled_in(solved, seen, self.config):
            self.band = None
            return TebChoice((0.0, 0.0), True, band)
        self.band = band.moved(inverse(odom))
        return TebChoice(self._command(band, velocity, speed_cap), False, band)

    def _rank(self, found: tuple[Band, float], seen: SeenObstacles) -> tuple[bool, bool, float]:
        band, cost = found
        now = feasible(band, seen, self.config)
        return not now, not feasible(band, seen, self.config, math.inf), cost

    def _warm_band(self, path: Floats, goal_yaw: float, odom: Pose) -> Band:
        """Last cycle's band in the robot's frame from its nearest pose on, with the
        robot as its start and the path's end as its goal; a fresh one when there is
        none or the goal has moved."""
        fresh = band_from_path(path, goal_yaw, self.config)
        if self.band is None:
            return fresh
        band = self.band.moved(odom)
        if (
            math.dist(band.poses[-1, :2], path[-1])
            > 2 * self.config.teb.dt_ref * self.config.body.max_linear
        ):
            return fresh
        nearest = int(np.argmin(np.hypot(band.poses[:, 0], band.poses[:, 1])))
        poses, dts = band.poses[nearest:].copy(), band.dts[nearest:].copy()
        if len(poses) < 2:
            return fresh
        poses[0] = (0.0, 0.0, 0.0)
        poses[-1] = (path[-1][0], path[-1][1], goal_yaw)
        return Band(poses, np.maximum(dts, MIN_DT))

    def _optimised(
        self, band: Band, path: Floats, velocity: Command, seen: SeenObstacles, final: bool
    ) -> tuple[Band, float]:
        """The band resized and optimised, and its cost (half the sum of squares)."""
        band = resized(band, self.config.teb)
        if len(band.poses) < 3:
            return band, 0.0
        problem = _problem(band, path, velocity, seen, final, self.config)
        x0 = problem.pack(band)
        result = least_squares(
            problem.residuals,
            x0,
            jac=problem.jacobian,
            method="trf",
            tr_solver="lsmr",
            tr_options={"maxiter": LSMR_ITERATIONS},
            max_nfev=self.config.teb.iterations,
            xtol=1e-4,
            ftol=1e-4,
        )
        poses, dts = problem.unpack(result.x)
        poses[:, 2] = wrap(poses[:, 2])
        return Band(poses, dts.copy()), float(result.cost)

    def _command(self, band: Band, velocity: Command, speed_cap: float) -> Command:
        """The first interval's velocity, within what one period can reach."""
        linear, angular = band.velocities()
        body, period = self.config.body, self.config.period
        v = _clamp(
            float(linear[0]),
            velocity[0] - body.linear_accel * period,
            velocity[0] + body.linear_accel * period,
        )
        w = _clamp(
            float(angular[0]),
            velocity[1] - body.angular_accel * period,
            velocity[1] + body.angular_accel * period,
        )
        v = _clamp(v, -body.max_linear, min(body.max_linear, speed_cap))
        return v, _clamp(w, -body.max_angular, body.max_angular)


def _problem(
    band: Band,
    path: Floats,
    velocity: Command,
    seen: SeenObstacles,
    final: bool,
    config: RobotConfig,
) -> _Problem:
    """The optimisation of ``band``: obstacles near it predicted to each pose's time,
    via-points every ``via_spacing`` along ``path`` (none in an obstacle's way)."""
    inner = band.poses[1:-1]
    first, second, share = _probes(len(inner))
    times = share * band.times[first] + (1 - share) * band.times[second]
    near = _near_band(seen, band.poses)
    predicted = near.at(times) if len(near.points) else np.zeros((len(times), 0, 2))
    vias = _resampled(path, config.teb.via_spacing)[1:-1]
    if len(near.points) and len(vias):
        gap = np.hypot(*(vias[:, None, :] - near.points[None, :, :]).transpose(2, 0, 1)).min(axis=1)
        vias = vias[gap > config.body.radius + config.teb.min_obstacle_dist]
    if len(vias):
        nearest = np.argmin(
            np.hypot(*(vias[:, None, :] - inner[None, :, :2]).transpose(2, 0, 1)), axis=1
        )
    else:
        nearest = np.zeros(0, np.intp)
    start, goal = band.poses[0].copy(), band.poses[-1].copy()
    return _Problem(start, goal, velocity, predicted, vias, nearest, config, final)


def _near_band(seen: SeenObstacles, poses: Floats) -> SeenObstacles:
    """The returns within ``OBSTACLE_REACH`` of the band (where movers will be, too)."""
    if len(seen.points) == 0:
        return seen
    where = np.concatenate([seen.points, seen.at(2.0)])
    gap = np.hypot(*(where[:, None, :] - poses[None, :, :2]).transpose(2, 0, 1)).min(axis=1)
    keep = (gap[: len(seen.points)] < OBSTACLE_REACH) | (gap[len(seen.points) :] < OBSTACLE_REACH)
    return SeenObstacles(seen.points[keep], seen.velocities[keep])


SWERVE = 0.6
"""Metres a swerving band's initial guess passes beside the obstacle in its way."""
SWERVE_LENGTH = 0.7
"""Metres along the band over which that swerve fades (a Gaussian's deviation)."""


def _swerved(band: Band, seen: SeenObstacles, side: float, config: RobotConfig) -> Band:
    """``band`` bent ``SWERVE`` metres to its left (``side`` 1) or right (-1) around
    its pose nearest what it would meet; its start and goal stay."""
    if len(seen.points) == 0 or len(band.poses) < 3:
        return band
    predicted = seen.at(band.times)
    gap = np.hypot(*(predicted - band.poses[:, None, :2]).transpose(2, 0, 1)).min(axis=1)
    worst = int(np.argmin(gap[1:-1])) + 1
    along = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(band.poses[:, :2], axis=0).T))])
    shift = side * SWERVE * np.exp(-(((along - along[worst]) / SWERVE_LENGTH) ** 2))
    shift[0] = shift[-1] = 0.0
    heading = band.poses[:, 2]
    xy = band.poses[:, :2] + shift[:, None] * np.column_stack([-np.sin(heading), np.cos(heading)])
    yaw = np.arctan2(np.diff(xy[:, 1]), np.diff(xy[:, 0]))
    poses = np.column_stack([xy, np.concatenate([[0.0], yaw[1:], [heading[-1]]])])
    return Band(poses, _least_times(poses, config))


def feasible(
    band: Band, seen: SeenObstacles, config: RobotConfig, within: float | None = None
) -> bool:
    """Whether the band's first ``within`` seconds (``feasibility_time`` by default), at
    its poses and midway between them, keep the body's radius from every return
    predicted for that time (TEB's ``isTrajectoryFeasible``; speeds are no hard
    constraint: the command is clamped to the limits)."""
    if len(seen.points) == 0:
        return True
    times = band.times
    ahead = times <= (config.teb.feasibility_time if within is None else within)
    ahead[: min(2, len(ahead))] = True
    last = int(ahead.sum())
    xy, when = band.poses[:last, :2], times[:last]
    xy = np.concatenate([xy[1:], (xy[:-1] + xy[1:]) / 2])
    when = np.concatenate([when[1:], (when[:-1] + when[1:]) / 2])
    gap = np.hypot(*(seen.at(when) - xy[:, None, :]).transpose(2, 0, 1)).min(axis=1)
    return bool((gap >= config.body.radius).all())


def _walled_in(solved: list[tuple[Band, float]], seen: SeenObstacles, config: RobotConfig) -> bool:
    """Whether every band tried runs into something that stands still: no band gets
    through, however long it waits, so the global path must change."""
    if len(solved) < 2:
        return False  # the warm band was clear all along
    still = ~np.any(seen.velocities != 0, axis=1)
    standing = SeenObstacles(seen.points[still], seen.velocities[still])
    return not any(feasible(band, standing, config, math.inf) for band, _ in solved)


def _clamp(value: float, low: float, high: float) -> float:
    return max(low, min(high, value))


def local_path(
    path: Sequence[Point], start: Point, index: int, pose: Pose, horizon: float
) -> Floats:
    """The robot (the origin) then ``horizon`` metres of ``path`` from ``start`` (a
    point on segment ``index``), in the frame of the robot's ``pose``."""
    points, left = [pose[:2], start], horizon
    for nxt in path[index + 1 :]:
        step = math.dist(points[-1], nxt)
        if step >= left:
            f = left / step
            last = points[-1]
            points.append((last[0] + f * (nxt[0] - last[0]), last[1] + f * (nxt[1] - last[1])))
            break
        points.append(nxt)
        left -= step
    return transform(inverse(pose), np.array(points, np.float64))


def heading_at_end(path: Floats) -> float:
    """The direction of the path's last segment (0 for a single point)."""
    if len(path) < 2:
        return 0.0
    dx, dy = path[-1] - path[-2]
    return math.atan2(dy, dx)
