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
   at most three neighbouring poses and two intervals), solved as the original's g2o
   solves it: Levenberg-Marquardt steps on the exact Jacobian (written term by term),
   warm-started from the last cycle's band. A band has about 70 variables, so each
   step's damped normal equations are a small dense solve (NumPy's LAPACK, BLAS kept on
   one thread). SciPy's ``least_squares`` was the first choice, but its general
   machinery (``trf`` with LSMR, or MINPACK's ``lm``) cost about 1 ms per iteration
   here, so six iterations a cycle were all it could afford, and a band that had not
   converged drove at about 0.2 m/s; the loop below adds about 0.1 ms to each
   evaluation of the residuals and Jacobian.
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
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from threadpoolctl import ThreadpoolController

from cloudnav_core.params import RobotConfig, TebConfig
from cloudnav_core.se2 import Point, Pose, inverse, transform, wrap
from robots.agent.tracking import ObstacleTracker, SeenObstacles

Floats = NDArray[np.float64]
Command = tuple[float, float]

OBSTACLE_REACH = 1.0
"""Metres from the band beyond which laser returns are left out of its optimisation."""
OBSTACLES_PER_PROBE = 6
"""Returns each clearance probe of the band is optimised against (its nearest ones)."""
RETRY_AFTER = 0.5
"""Seconds between tries of other bands while the band runs into something beyond its
hard constraint's horizon (one that fails it tries them at once)."""
MIN_DT = 0.02
"""Seconds: the least time interval between two poses of a band."""
BLAS = ThreadpoolController()
"""NumPy's linear algebra libraries. A band's matrices are small (about 200 by 70):
BLAS threads cost more to wake and wait for than they save (a normal-equations product
took 0.53 ms of CPU on two threads against 0.03 ms on one, on the 2-core machine), so
the planner runs them on one thread."""


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
    obstacles predicted at each probe's time (``(probes, k, 2)``, see ``_probes``) with
    the extra room each asks for (``margins``, ``(probes, k)``: movers'), the
    via-points and the inner pose each pulls, and whether the goal is the target itself
    (to be reached at rest).

    Variables ``x``: the inner poses' ``(x, y, yaw)`` then the ``n`` intervals (as
    ``pack`` writes them). Rows of the residuals and of the Jacobian (both exact,
    computed together by ``_Terms``): kinematics, driving backwards, linear and angular
    speed beyond the limits (``n`` each), linear and angular acceleration beyond the
    limits (``n + 1`` each), time (``n``), clearance and inflation (one per probe),
    via-points (x and y each).
    """

    def __init__(
        self,
        start: Floats,
        goal: Floats,
        velocity: Command,
        obstacles: Floats,
        margins: Floats,
        vias: Floats,
        via_poses: NDArray[np.intp],
        config: RobotConfig,
        final: bool,
    ) -> None:
        self.start, self.goal, self.velocity = start, goal, velocity
        self.obstacles, self.margins = obstacles, margins
        self.vias, self.via_poses = vias, via_poses
        self.config, self.final = config, final
        self.inner = int(obstacles.shape[0]) // 2  # probes: inner poses and midpoints
        self.layout = _Layout(self.inner + 1)
        self.flat_index: NDArray[np.intp] | None = None  # see _Terms._jacobian

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
        return self.evaluate(x)[0]

    def jacobian(self, x: Floats) -> Floats:
        return self.evaluate(x)[1]

    def evaluate(self, x: Floats) -> tuple[Floats, Floats]:
        """The residuals at ``x`` and their Jacobian with respect to ``x``."""
        residuals, jacobian = _Terms(self, x).stacked()
        m = self.inner
        jacobian[:, 3 * m :] *= np.exp(x[3 * m :])  # d(dt)/d(variable)
        return residuals, jacobian


def _probes(inner: int) -> tuple[NDArray[np.intp], NDArray[np.intp], Floats]:
    """Where a band of ``inner`` inner poses is checked for clearance: pose indices
    ``first`` and ``second`` and the ``share`` of the first (the inner poses, then the
    midpoints of the ``inner + 1`` intervals)."""
    poses, intervals = np.arange(1, inner + 1), np.arange(inner + 1)
    first = np.concatenate([poses, intervals])
    second = np.concatenate([poses, intervals + 1])
    return first, second, np.concatenate([np.ones(inner), np.full(inner + 1, 0.5)])


class _Layout:
    """Where the rows of a band of ``n`` intervals put their derivatives, worked out once
    per problem: the Jacobian's columns while it is written are every pose's
    ``(x, y, yaw)`` (the fixed start and goal included, dropped at the end), then each
    interval's time."""

    def __init__(self, n: int) -> None:
        self.n = n
        self.width = 3 * (n + 1) + n
        self.intervals = i = np.arange(n)
        # Per interval: its two poses' components, then its own time.
        self.interval = np.column_stack(
            [3 * i, 3 * i + 1, 3 * i + 2, 3 * i + 3, 3 * i + 4, 3 * i + 5, 3 * (n + 1) + i]
        )
        self.times = self.time(i)[:, None]
        self.variables = np.r_[3 : 3 * n, 3 * (n + 1) : self.width]
        self.first, self.second, self.share = _probes(n - 1)
        self.probe_columns = np.hstack([self.pose(self.first), self.pose(self.second)])
        # Acceleration rows 0..n: d(span)/d(dt) of row 0 on interval 0, of inner rows half
        # on either side, of the last row on the last interval.
        self.accelerations = k = np.arange(n + 1)
        self.span_rows = np.concatenate([[0], k[1:-1], k[1:-1], [n]])
        self.span_times = self.time(np.concatenate([[0], k[1:-1] - 1, k[1:-1], [n - 1]]))[:, None]
        self.span_share = np.concatenate([[1.0], np.full(2 * (n - 1), 0.5), [1.0]])

    def pose(self, index: NDArray[np.intp]) -> NDArray[np.intp]:
        """The ``(x, y)`` columns of each pose of ``index``: ``(len(index), 2)``."""
        return np.column_stack([3 * index, 3 * index + 1])

    def time(self, interval: NDArray[np.intp]) -> NDArray[np.intp]:
        return 3 * (self.n + 1) + interval


class _Terms:
    """The residuals and Jacobian of one ``_Problem`` at one ``x``, written term by term
    as entries (row, column, value) of a dense matrix built once at the end."""

    def __init__(self, problem: _Problem, x: Floats) -> None:
        self.problem, self.teb, self.body = problem, problem.config.teb, problem.config.body
        self.layout = problem.layout
        self.poses, self.dts = problem.unpack(x)
        self.n = problem.inner + 1
        self.values: list[Floats] = []
        self.entries: list[tuple[NDArray[np.intp], NDArray[np.intp], Floats]] = []
        self.count = 0  # rows written so far
        delta = np.diff(self.poses[:, :2], axis=0)
        self.dx, self.dy = delta[:, 0], delta[:, 1]
        self.dist = np.maximum(np.hypot(self.dx, self.dy), 1e-9)
        self.c, self.s = np.cos(self.poses[:, 2]), np.sin(self.poses[:, 2])
        self.forward = self.dx * self.c[:-1] + self.dy * self.s[:-1]
        self.sign = np.where(self.forward >= 0, 1.0, -1.0)
        self.linear = self.sign * self.dist / self.dts
        self.angular = wrap(np.diff(self.poses[:, 2])) / self.dts
        self.speed_gradients = self._speed_gradients()

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
        return np.concatenate(self.values), self._jacobian()

    # --- bookkeeping ---

    def _add(
        self,
        weight: float,
        values: Floats,
        entries: Sequence[tuple[NDArray[np.intp], NDArray[np.intp], Floats]],
    ) -> None:
        """Rows ``values`` (times the root of ``weight``) and their derivatives: per
        entry, each row's (a row index within ``values``) columns and values, ``(k, w)``."""
        root = math.sqrt(weight)
        self.values.append(root * values)
        for rows, columns, derivatives in entries:
            self.entries.append((self.count + rows, columns, root * derivatives))
        self.count += len(values)

    def _jacobian(self) -> Floats:
        """The entries as a dense matrix; where they go depends on the band's size
        only, so it is worked out once per problem."""
        problem, width = self.problem, self.layout.width
        if problem.flat_index is None:
            problem.flat_index = np.concatenate(
                [(rows[:, None] * width + columns).ravel() for rows, columns, _ in self.entries]
            )
        values = np.concatenate([v.ravel() for _, _, v in self.entries])
        flat = np.bincount(problem.flat_index, values, self.count * width).astype(
            np.float64, copy=False
        )
        return flat.reshape(self.count, width)[:, self.layout.variables]

    def _speed_gradients(self) -> tuple[Floats, Floats]:
        """Per interval, the derivatives of its linear and of its angular velocity with
        respect to its ``_Layout.interval`` columns, ``(n, 7)`` each."""
        zeros = np.zeros(self.n)
        step = self.sign / (self.dist * self.dts)
        ux, uy = step * self.dx, step * self.dy
        linear = np.column_stack([-ux, -uy, zeros, ux, uy, zeros, -self.linear / self.dts])
        turn = 1.0 / self.dts
        angular = np.column_stack(
            [zeros, zeros, -turn, zeros, zeros, turn, -self.angular / self.dts]
        )
        return linear, angular

    def _speed_entry(
        self, rows: NDArray[np.intp], interval: NDArray[np.intp], scale: Floats, part: int
    ) -> tuple[NDArray[np.intp], NDArray[np.intp], Floats]:
        """``scale`` times the derivative of interval ``interval``'s linear (``part`` 0)
        or angular (1) velocity, in ``rows``."""
        gradient = self.speed_gradients[part][interval]
        return rows, self.layout.interval[interval], scale[:, None] * gradient

    # --- the objectives ---

    def _kinematics(self, weight: float) -> None:
        """Non-holonomic: both headings make the same angle with the step between them."""
        c, s, i = self.c, self.s, self.layout.intervals
        cc, ss = c[:-1] + c[1:], s[:-1] + s[1:]
        gradient = np.column_stack(
            [
                ss,
                -cc,
                -s[:-1] * self.dy - c[:-1] * self.dx,
                -ss,
                cc,
                -s[1:] * self.dy - c[1:] * self.dx,
            ]
        )
        self._add(weight, cc * self.dy - ss * self.dx, [(i, self.layout.interval[:, :6], gradient)])

    def _backwards(self, weight: float) -> None:
        i, active = self.layout.intervals, (self.forward < 0).astype(np.float64)
        c, s = self.c[:-1], self.s[:-1]
        gradient = active[:, None] * np.column_stack([c, s, self.dx * s - self.dy * c, -c, -s])
        self._add(
            weight, np.maximum(-self.forward, 0.0), [(i, self.layout.interval[:, :5], gradient)]
        )

    def _speed_limits(self, weight: float, max_linear: float, max_angular: float) -> None:
        i = self.layout.intervals
        for part, speed, limit in ((0, self.linear, max_linear), (1, self.angular, max_angular)):
            excess = np.abs(speed) - limit
            scale = np.where(excess > 0, np.sign(speed), 0.0)
            self._add(weight, np.maximum(excess, 0.0), [self._speed_entry(i, i, scale, part)])

    def _acceleration_limits(self, weight: float, max_linear: float, max_angular: float) -> None:
        """Between the start velocity and the first interval, each two intervals, and
        (for the final goal) the last interval and rest."""
        dts, final, layout = self.dts, self.problem.final, self.layout
        spans = np.concatenate([[dts[0]], (dts[:-1] + dts[1:]) / 2, [dts[-1]]])
        k = layout.accelerations
        for part, speed, limit in ((0, self.linear, max_linear), (1, self.angular, max_angular)):
            end = 0.0 if final else speed[-1]
            v = np.concatenate([[self.problem.velocity[part]], speed, [end]])
            accel = np.diff(v) / spans
            excess = np.abs(accel) - limit
            scale = (excess > 0) * np.sign(accel) / spans
            if not final:
                scale[-1] = 0.0  # the last interval's velocity to itself: no term
            spanning = (-scale * accel)[layout.span_rows] * layout.span_share
            entries = [
                self._speed_entry(k[:-1], k[:-1], scale[:-1], part),
                self._speed_entry(k[1:], k[1:] - 1, -scale[1:], part),
                (layout.span_rows, layout.span_times, spanning[:, None]),
            ]
            self._add(weight, np.maximum(excess, 0.0), entries)

    def _time(self, weight: float) -> None:
        entry = (self.layout.intervals, self.layout.times, np.ones((self.n, 1)))
        self._add(weight, self.dts.copy(), [entry])

    def _clearance(self, hinges: list[tuple[float, float]]) -> None:
        """Per probe (each inner pose, then each interval's midpoint, so that no obstacle
        slips between two poses), how far inside each of ``hinges`` (weight, distance)
        the nearest return predicted for its time lies (a mover's margin nearer)."""
        layout = self.layout
        share = layout.share[:, None]
        probes = share * self.poses[layout.first, :2] + (1 - share) * self.poses[layout.second, :2]
        obstacles, count = self.problem.obstacles, len(share)
        rows = np.arange(count)
        if obstacles.shape[1] == 0:
            distance, away = np.full(count, np.inf), np.zeros((count, 2))
        else:
            gap = probes[:, None, :] - obstacles
            reach = np.sqrt((gap**2).sum(axis=2))
            closest = np.argmin(reach - self.problem.margins, axis=1)
            away = gap[rows, closest] / np.maximum(reach[rows, closest], 1e-9)[:, None]
            # A mover is kept its margin farther off: as if it were that much nearer.
            distance = reach[rows, closest] - self.problem.margins[rows, closest]
        for weight, reach in hinges:
            pushed = (distance < reach)[:, None] * -away
            gradient = np.hstack([share * pushed, (1 - share) * pushed])
            entry = (rows, layout.probe_columns, gradient)
            self._add(weight, np.maximum(reach - distance, 0.0), [entry])

    def _vias(self, weight: float) -> None:
        pulled = self.problem.via_poses + 1
        count = len(pulled)
        values = (self.poses[pulled, :2] - self.problem.vias).ravel()
        columns = self.layout.pose(pulled).reshape(-1, 1)
        self._add(weight, values, [(np.arange(2 * count), columns, np.ones((2 * count, 1)))])


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
        self._retried_at = -math.inf  # when other bands were last tried

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
        with BLAS.limit(limits=1, user_api="blas"):
            return self._choose(path, goal_yaw, final, velocity, points, odom, seconds, speed_cap)

    def _choose(
        self,
        path: Floats,
        goal_yaw: float,
        final: bool,
        velocity: Command,
        points: Floats,
        odom: Pose,
        seconds: float,
        speed_cap: float,
    ) -> TebChoice:
        seen = self.tracker.update(points, odom, seconds)
        fresh = band_from_path(path, goal_yaw, self.config)
        warm = self._warm_band(fresh, path, goal_yaw, odom)
        iterations = self.config.teb.iterations
        tried = [self._tried(warm, path, velocity, seen, final, iterations)]
        if tried[0].contact < math.inf and (
            not tried[0].feasible or seconds - self._retried_at >= RETRY_AFTER
        ):
            # Something in the band's way: replan it, from the path and swerving either
            # way round the first thing it meets (two homotopy classes of the original's
            # many), and keep the best: feasible now, clear all along, cheapest. Each
            # try has half the evaluations: the one kept goes on from there next cycle.
            self._retried_at = seconds
            swerves = [_swerved(fresh, seen, side, self.config) for side in (1.0, -1.0)]
            starts = swerves if warm is fresh else [fresh, *swerves]
            evaluations = max(2, iterations // 2)
            tried += [self._tried(b, path, velocity, seen, final, evaluations) for b in starts]
        best = min(tried, key=lambda t: (not t.feasible, t.contact < math.inf, t.cost))
        if not best.feasible or _walled_in(tried, seen, self.config):
            self.band = None
            return TebChoice((0.0, 0.0), True, best.band)
        self.band = best.band.moved(inverse(odom))
        return TebChoice(self._command(best.band, velocity, speed_cap), False, best.band)

    def _tried(
        self,
        band: Band,
        path: Floats,
        velocity: Command,
        seen: SeenObstacles,
        final: bool,
        evaluations: int,
    ) -> _Tried:
        optimised, cost = self._optimised(band, path, velocity, seen, final, evaluations)
        contact = contact_time(optimised, seen, self.config)
        return _Tried(optimised, cost, contact, feasible_until(optimised, self.config) < contact)

    def _warm_band(self, fresh: Band, path: Floats, goal_yaw: float, odom: Pose) -> Band:
        """Last cycle's band in the robot's frame from its nearest pose on, with the
        robot as its start and the path's end as its goal; ``fresh`` (the band from the
        path) when there is none or the goal has moved."""
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
        self,
        band: Band,
        path: Floats,
        velocity: Command,
        seen: SeenObstacles,
        final: bool,
        evaluations: int,
    ) -> tuple[Band, float]:
        """The band resized and optimised with at most ``evaluations`` evaluations, and
        its cost (half the sum of squares)."""
        band = resized(band, self.config.teb)
        if len(band.poses) < 3:
            return band, 0.0
        problem = _problem(band, path, velocity, seen, final, self.config)
        x, cost = levenberg_marquardt(problem.evaluate, problem.pack(band), evaluations)
        poses, dts = problem.unpack(x)
        poses[:, 2] = wrap(poses[:, 2])
        return Band(poses, dts.copy()), cost

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


def levenberg_marquardt(
    evaluate: Callable[[Floats], tuple[Floats, Floats]],
    x: Floats,
    evaluations: int,
    tolerance: float = 1e-4,
) -> tuple[Floats, float]:
    """``x`` moved to lower half the sum of squares of the residuals ``evaluate``
    returns (with their Jacobian), and that cost, after at most ``evaluations``
    evaluations or once a step gains less than ``tolerance`` of the cost.

    Levenberg-Marquardt with Nielsen's damping update, as g2o runs it for the original
    planner: each step solves the damped normal equations (small and dense here)."""
    residuals, jacobian = evaluate(x)
    cost = 0.5 * float(residuals @ residuals)
    hessian, gradient = jacobian.T @ jacobian, jacobian.T @ residuals
    damping, growth = 1e-3 * float(hessian.diagonal().max()), 2.0
    identity = np.eye(len(x))
    for _ in range(evaluations - 1):
        step = np.linalg.solve(hessian + damping * identity, -gradient)
        trial_residuals, trial_jacobian = evaluate(x + step)
        trial_cost = 0.5 * float(trial_residuals @ trial_residuals)
        predicted = -float(gradient @ step + 0.5 * step @ hessian @ step)
        gain = (cost - trial_cost) / predicted if predicted > 0 else -1.0
        if gain <= 0:
            damping, growth = damping * growth, growth * 2
            continue
        x, converged = x + step, cost - trial_cost < tolerance * cost
        cost, jacobian = trial_cost, trial_jacobian
        hessian, gradient = jacobian.T @ jacobian, jacobian.T @ trial_residuals
        damping, growth = damping * max(1 / 3, 1 - (2 * gain - 1) ** 3), 2.0
        if converged:
            break
    return x, cost


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
    probes = share[:, None] * band.poses[first, :2] + (1 - share)[:, None] * band.poses[second, :2]
    moving = np.any(near.velocities != 0, axis=1)
    predicted, moving = _nearest_each(near.at(times), moving, probes)
    margins = np.where(moving, config.teb.dynamic_obstacle_dist, 0.0)
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
    return _Problem(start, goal, velocity, predicted, margins, vias, nearest, config, final)


def _nearest_each(
    predicted: Floats, moving: NDArray[np.bool_], probes: Floats
) -> tuple[Floats, NDArray[np.bool_]]:
    """Of ``predicted`` ``(probes, k, 2)``, the ``OBSTACLES_PER_PROBE`` nearest each
    probe's place at the start (the original planner also ties each pose to its nearest
    obstacles once per optimisation), and whether each of those ``moving``; the
    hard-constraint check still sees them all."""
    if predicted.shape[1] <= OBSTACLES_PER_PROBE:
        return predicted, np.broadcast_to(moving, predicted.shape[:2])
    squared = ((predicted - probes[:, None, :]) ** 2).sum(axis=2)
    nearest = np.argpartition(squared, OBSTACLES_PER_PROBE - 1, axis=1)[:, :OBSTACLES_PER_PROBE]
    return np.take_along_axis(predicted, nearest[:, :, None], axis=1), moving[nearest]


def _near_band(seen: SeenObstacles, poses: Floats) -> SeenObstacles:
    """The returns within ``OBSTACLE_REACH`` of the band now or in 2 s (where movers
    will be); those outside the band's box widened by that reach are dropped first."""
    if len(seen.points) == 0:
        return seen
    low = poses[:, :2].min(axis=0) - OBSTACLE_REACH
    high = poses[:, :2].max(axis=0) + OBSTACLE_REACH
    now, later = seen.points, seen.at(2.0)
    boxed = np.all((now > low) & (now < high), axis=1) | np.all(
        (later > low) & (later < high), axis=1
    )
    near = SeenObstacles(now[boxed], seen.velocities[boxed])
    where = np.stack([near.points, later[boxed]])  # (2, k, 2)
    squared = ((where[:, :, None, :] - poses[None, None, :, :2]) ** 2).sum(axis=3)
    keep = (squared.min(axis=2) < OBSTACLE_REACH**2).any(axis=0)
    return SeenObstacles(near.points[keep], near.velocities[keep])


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


@dataclass(frozen=True)
class _Tried:
    """An optimised band, its cost, when it first comes within the body's radius of
    something (``inf``: never), and whether that is beyond its hard-constraint check."""

    band: Band
    cost: float
    contact: float
    feasible: bool


def contact_time(band: Band, seen: SeenObstacles, config: RobotConfig) -> float:
    """Seconds into the band of its first pose or midpoint between poses nearer than
    the body's radius to a return predicted for that time; ``inf`` when none is."""
    if len(seen.points) == 0 or len(band.poses) < 2:
        return math.inf
    xy, times = band.poses[:, :2], band.times
    probes = np.concatenate([xy[1:], (xy[:-1] + xy[1:]) / 2])
    when = np.concatenate([times[1:], (times[:-1] + times[1:]) / 2])
    gap = ((seen.at(when) - probes[:, None, :]) ** 2).sum(axis=2).min(axis=1)
    touching = when[gap < config.body.radius**2]
    return float(touching.min()) if len(touching) else math.inf


def feasible_until(band: Band, config: RobotConfig) -> float:
    """Seconds of ``band`` its hard constraint covers: ``feasibility_time``, and at least
    its first interval (TEB's ``isTrajectoryFeasible``; speeds are no hard constraint:
    the command is clamped to the limits)."""
    return max(config.teb.feasibility_time, float(band.times[min(1, len(band.dts))]))


def _walled_in(tried: list[_Tried], seen: SeenObstacles, config: RobotConfig) -> bool:
    """Whether every band tried runs into something that stands still: no band gets
    through, however long it waits, so the global path must change."""
    if len(tried) < 2:
        return False  # the warm band was clear all along
    still = ~np.any(seen.velocities != 0, axis=1)
    standing = SeenObstacles(seen.points[still], seen.velocities[still])
    return all(contact_time(t.band, standing, config) < math.inf for t in tried)


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
