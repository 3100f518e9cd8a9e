"""Navigation: goals and their actionlib statuses, the global plan, the local controller.

- ``GoalBoard`` keeps goals as an actionlib action server does: a new goal preempts the
  active one (PREEMPTED), a cancel preempts it too, and each ends SUCCEEDED or ABORTED;
  ``status_array`` turns it into ``nav_status``.
- ``Driver`` drives to one target pose: A* on the current sub-map's inflated grid
  (``maps.domain.planning``, the planner the server uses), then a local planner that
  follows the path and keeps clear of what the laser sees, mapped or not: a dynamic
  window controller (``DynamicWindow``) on what it sees now (``LocalObstacles``), or
  the timed elastic band (``robots.agent.teb``) on what it sees with the velocities of
  what moves, as the robot's ``local_planner`` parameter says. When the path ahead runs
  into something the laser sees (at most every ``REPLAN_INTERVAL`` seconds), the driver plans again
  with the laser's returns marked on the grid, as Nav2's obstacle layer does in its
  global costmap. Blocked for ``BLOCKED_REPLAN`` seconds, or without progress for
  ``STUCK_AFTER``, it does the same; after ``MAX_REPLANS`` of those with no progress
  between them it gives up. A plan around what the laser sees that finds no way keeps
  the last path and waits: what blocks a doorway is often a person who will move on.
- ``Navigator`` joins them to the Maps Supervisor: each tick the supervisor says which
  leg comes next (search, approach a tag, the goal itself), the driver drives it, and
  the board records how the goal ends. The driver is a ``LegDriver``: the agent's own
  ``Driver``, or ``robots.agent.stack.StackDriver``, which hands each leg to the robot's
  own navigation stack (move_base, Nav2) as a goal.

Frames: targets, paths and the pose estimate share the frame of the current sub-map
(the building's); obstacles and the controller's trajectories are in the robot's frame.

Settings: the body's limits and radius, the planner's margin and the controller's tuning
all come from the robot's ``RobotConfig`` (``robots.domain.params``).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from enum import Enum
from typing import Protocol

import cv2
import numpy as np
from numpy.typing import NDArray

from maps.domain.planning import Costmap, OutOfMapError, PlanningError, plan_on
from robots.agent.supervisor import SEARCH_RATE, Destination, Leg, LegKind, MapsSupervisor, SubMap
from robots.agent.teb import TimedElasticBand, heading_at_end, local_path
from robots.agent.tracking import ObstacleTracker, SeenObstacles
from robots.domain.params import RobotConfig
from robots.domain.se2 import Point, Pose, compose, inverse, transform, wrap
from telemetry.domain.messages import GoalStatus, StatusEntry

Command = tuple[float, float]
Floats = NDArray[np.float64]

STOP: Command = (0.0, 0.0)
BLOCKED_REPLAN = 1.0
"""Seconds without an admissible trajectory before planning around what the laser sees."""
STUCK_AFTER = 6.0
"""Seconds without getting ``PROGRESS`` metres nearer before planning again."""
PROGRESS = 0.1
MAX_REPLANS = 4
RETARGET = 0.15
"""Metres a target may move (a tag seen more precisely) before the path is planned again."""
MARK_RANGE = 3.0
"""Metres: laser returns within this range are marked on the grid when replanning."""
LOOK_AHEAD = 2.0
"""Metres of path checked against the laser's returns each tick."""
REPLAN_INTERVAL = 1.0
"""Seconds between plans made because the path ahead runs into something seen."""


# --- goals -----------------------------------------------------------------------------


@dataclass
class GoalBoard:
    """Goals and their statuses; ``version`` grows with every change."""

    keep: int = 5
    entries: list[StatusEntry] = field(default_factory=list)
    version: int = 0
    _count: int = 0

    @property
    def active(self) -> StatusEntry | None:
        last = self.entries[-1] if self.entries else None
        return last if last is not None and not last.status.terminal else None

    def start(self, seconds: float, prefix: str = "goal") -> StatusEntry:
        """A new ACTIVE goal; the one it replaces, if active, is PREEMPTED."""
        self.finish(GoalStatus.PREEMPTED, "preempted by a new goal")
        self._count += 1
        entry = StatusEntry(f"{prefix}_{self._count}", seconds, GoalStatus.ACTIVE, "accepted")
        self.entries = [*self.entries, entry][-self.keep :]
        self.version += 1
        return entry

    def finish(self, status: GoalStatus, text: str) -> bool:
        """End the active goal with ``status``; False if none was active."""
        return self._update(status, text) if self.active is not None else False

    def describe(self, text: str) -> None:
        """Say what the active goal is doing now."""
        active = self.active
        if active is not None and active.text != text:
            self._update(active.status, text)

    def _update(self, status: GoalStatus, text: str) -> bool:
        last = self.entries[-1]
        self.entries[-1] = StatusEntry(last.goal_id, last.stamp, status, text)
        self.version += 1
        return True


# --- what the laser sees ---------------------------------------------------------------


class LocalObstacles:
    """Clearance around the robot: distance from points of the robot's frame to the
    nearest laser return, on a square grid ``reach`` metres each way.

    Points off that grid are taken as clear (``reach``): the controller never looks that
    far. Distances are between cell centres, less half a cell, so they err short.
    """

    def __init__(self, points: Floats, reach: float = 2.5, resolution: float = 0.05) -> None:
        self.points = points  # laser returns, robot frame, shape (n, 2)
        self.reach, self.resolution = reach, resolution
        self.size = round(2 * reach / resolution)
        cells = self._cells(points[:, 0], points[:, 1]) if len(points) else None
        self._distance = _clearance_grid(self.size, cells, resolution)

    @classmethod
    def from_scan(cls, ranges: Floats, angles: Floats) -> LocalObstacles:
        """From a scan's ranges (``inf`` = no return) at ``angles`` in the robot frame."""
        hit = np.isfinite(ranges)
        distance, angle = ranges[hit], angles[hit]
        return cls(np.stack([distance * np.cos(angle), distance * np.sin(angle)], 1))

    def clearance(self, x: Floats, y: Floats) -> Floats:
        """Clearance in metres at each robot-frame point ``(x, y)`` (arrays of one shape)."""
        rows, cols = self._cells(x, y)
        inside = (rows >= 0) & (rows < self.size) & (cols >= 0) & (cols < self.size)
        found = self._distance[np.where(inside, rows, 0), np.where(inside, cols, 0)]
        return np.where(inside, found, self.reach)

    def _cells(self, x: Floats, y: Floats) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
        rows = np.floor((np.asarray(y) + self.reach) / self.resolution).astype(np.intp)
        cols = np.floor((np.asarray(x) + self.reach) / self.resolution).astype(np.intp)
        return rows, cols


def _clearance_grid(
    size: int, cells: tuple[NDArray[np.intp], NDArray[np.intp]] | None, resolution: float
) -> Floats:
    """Metres from each cell to the nearest marked one (``inf`` with none marked)."""
    if cells is None:
        return np.full((size, size), np.inf)
    rows, cols = cells
    inside = (rows >= 0) & (rows < size) & (cols >= 0) & (cols < size)
    free = np.full((size, size), 255, np.uint8)
    free[rows[inside], cols[inside]] = 0
    if inside.sum() == 0:
        return np.full((size, size), np.inf)
    distance = cv2.distanceTransform(free, cv2.DIST_L2, cv2.DIST_MASK_PRECISE)
    return np.maximum(np.asarray(distance, np.float64) - 0.5, 0.0) * resolution


CELL = 0.05
"""Metres: the clearance grid's cell (``LocalObstacles``' resolution)."""


@dataclass
class _Clearance:
    """Clearance from what stands (a ``LocalObstacles`` grid for returns farther than
    ``EXACT_REACH``, exact distances to the nearer ones, so that a robot close to
    something cannot creep nearer within one cell of the grid) and from what moves
    (returns predicted at constant velocity, counted ``margin`` nearer than they are)."""

    still: LocalObstacles
    near: Floats
    movers: SeenObstacles
    margin: float = 0.0

    @classmethod
    def of(cls, seen: SeenObstacles, obstacles: LocalObstacles) -> _Clearance:
        """``seen`` split into what stands, far and near, and what moves within
        ``MOVER_REACH``."""
        moving = np.any(seen.velocities != 0, axis=1)
        distance = np.hypot(seen.points[:, 0], seen.points[:, 1])
        near = ~moving & (distance < EXACT_REACH)
        far = ~moving & ~near
        still = LocalObstacles(seen.points[far], obstacles.reach, obstacles.resolution)
        movers = moving & (distance <= MOVER_REACH)
        return cls(
            still, seen.points[near], SeenObstacles(seen.points[movers], seen.velocities[movers])
        )

    def along(self, xs: Floats, ys: Floats, times: Floats) -> Floats:
        """Clearance at each point ``(xs, ys)`` (robot frame, shape (arcs, steps)) at
        the step's time in ``times`` (steps,)."""
        clear = self.still.clearance(xs, ys)
        if len(self.near):
            clear = np.minimum(clear, _nearest(xs, ys, self.near[None, :, :]))
        if len(self.movers.points):
            clear = np.minimum(clear, _nearest(xs, ys, self.movers.at(times)) - self.margin)
        return np.asarray(clear)

    def here(self) -> float:
        """Clearance at the robot now."""
        zero = np.zeros((1, 1))
        return float(self.along(zero, zero, np.zeros(1))[0, 0])


def _nearest(xs: Floats, ys: Floats, points: Floats) -> Floats:
    """Distance from each point ``(xs, ys)`` (arcs, steps) to the nearest of ``points``
    at its step, (steps, n, 2), or the same ``points`` at every step, (1, n, 2)."""
    dx = xs[:, :, None] - points[None, :, :, 0]
    dy = ys[:, :, None] - points[None, :, :, 1]
    return np.asarray(np.sqrt((dx * dx + dy * dy).min(axis=2)))


EXACT_REACH = 0.6
"""Metres: returns that stand nearer than this are measured exactly, not on the grid."""
MOVER_REACH = 3.5
"""Metres: returns that move farther than this are left out (at walking speed and the
robot's, they cannot come within reach over the horizon)."""


# --- the local controller --------------------------------------------------------------


@dataclass(frozen=True)
class Choice:
    """The controller's command, and whether every way forward was blocked."""

    command: Command
    blocked: bool = False


class DynamicWindow:
    """The dynamic window approach (Fox, Burgard and Thrun, 1997) for a round robot,
    among things that move.

    Velocities reachable within one ``period`` under the acceleration limits are sampled
    and each held for ``horizon`` seconds. The laser's returns are tracked
    (``robots.agent.tracking``, the tracker TEB uses): those that stand are kept on a
    clearance grid, and those that move (people, robots) are predicted at constant
    velocity to each step's time, counting ``dynamic_obstacle_dist`` nearer than they
    are. Arcs that come closer than ``radius + safety`` to either are inadmissible (when
    the robot already stands closer, those that come no nearer than it is, and never
    within half a cell of touching, stay admissible, so it can leave). The rest are scored
    by how near their end comes to the carrot, whether they end facing it, their
    clearance and their speed. With no way forward, the robot stops, or backs away at
    ``back_off`` when something moving would run into it where it stands within half
    the horizon.
    """

    def __init__(self, config: RobotConfig) -> None:
        self.config = config
        self.tracker = ObstacleTracker()
        steps = round(config.controller.horizon / config.period)
        self._times: Floats = np.arange(1, steps + 1, dtype=np.float64) * config.period

    def choose(
        self,
        velocity: Command,
        carrot: Point,
        obstacles: LocalObstacles,
        speed_cap: float,
        odom: Pose = (0.0, 0.0, 0.0),
        seconds: float = 0.0,
    ) -> Choice:
        """The best command toward ``carrot`` (robot frame) at most ``speed_cap`` m/s;
        ``obstacles`` were seen at ``seconds`` with the odometry at ``odom`` (which lets
        the tracker tell what moves)."""
        clearance = _Clearance.of(self.tracker.update(obstacles.points, odom, seconds), obstacles)
        clearance.margin = self.config.controller.dynamic_obstacle_dist
        linear, angular = self._samples(velocity, speed_cap)
        xs, ys, headings = self._rollout(linear, angular)
        along = clearance.along(xs, ys, self._times)
        admissible = self._admissible(along, clearance.here())
        forward = admissible & (linear > 0.02)
        if not forward.any():
            can_turn = bool(admissible.any())
            return Choice(self._no_way_forward(velocity, carrot, clearance, can_turn), True)
        cost = self._cost(xs[:, -1], ys[:, -1], headings[:, -1], carrot, along.min(axis=1), linear)
        best = int(np.argmin(np.where(forward, cost, np.inf)))
        return Choice((float(linear[best]), float(angular[best])))

    def _admissible(self, along: Floats, here: float) -> NDArray[np.bool_]:
        """Arcs that keep ``radius + safety`` clear all along; or, when the robot stands
        nearer than that already, come no nearer (one cell of slack for the grid's
        steps, but none within half a cell of touching) and end farther away."""
        radius = self.config.body.radius
        needed = radius + self.config.controller.safety
        clear = along.min(axis=1)
        if here >= needed:
            return np.asarray(clear >= needed)
        floor = min(here, max(here - CELL, radius + CELL / 2))
        return np.asarray((clear >= floor) & (along[:, -1] > here))

    def _no_way_forward(
        self, velocity: Command, carrot: Point, clearance: _Clearance, can_turn: bool
    ) -> Command:
        """Back away from something moving that would run into the robot where it
        stands within half the horizon, if backing puts that off; else turn toward the
        carrot, or stop. (A person who is about to stop for the robot is no reason to
        back away: only a meeting that near is.)"""
        soon = self._times[: len(self._times) // 2]
        still = np.zeros((1, len(soon)))
        standing = self._conflict_steps(clearance.along(still, still, soon))[0]
        if standing < len(soon):
            back = self._backwards(velocity, clearance, standing)
            if back is not None:
                return back
        return self._turn_toward(carrot) if can_turn else STOP

    def _backwards(self, velocity: Command, clearance: _Clearance, standing: int) -> Command | None:
        """The straight way back at up to ``back_off`` that meets something latest, if
        no sooner than the ``standing`` step of standing still (backing off from a fast
        walker may not put the meeting off a whole step, but softens it)."""
        body, period = self.config.body, self.config.period
        speed = max(-self.config.controller.back_off, velocity[0] - body.linear_accel * period)
        linear = np.array([speed, speed / 2])
        xs, ys, _ = self._rollout(linear, np.zeros(2))
        conflict = self._conflict_steps(clearance.along(xs, ys, self._times))
        best = int(np.argmax(conflict))
        return (float(linear[best]), 0.0) if conflict[best] >= standing else None

    def _conflict_steps(self, along: Floats) -> NDArray[np.intp]:
        """Per arc, the first step within the body's radius of something (movers'
        margin counted); the number of steps when none is."""
        near = along < self.config.body.radius
        return np.asarray(np.where(near.any(axis=1), near.argmax(axis=1), near.shape[1]), np.intp)

    def _samples(self, velocity: Command, speed_cap: float) -> tuple[Floats, Floats]:
        """Linear and angular velocities of every sample (flattened grid)."""
        body, period, (v0, w0) = self.config.body, self.config.period, velocity
        top = min(body.max_linear, speed_cap, v0 + body.linear_accel * period)
        bottom = min(max(0.0, v0 - body.linear_accel * period), top)
        w_low = max(-body.max_angular, w0 - body.angular_accel * period)
        w_high = min(body.max_angular, w0 + body.angular_accel * period)
        linear = np.linspace(bottom, top, self.config.controller.linear_samples)
        angular = np.linspace(w_low, w_high, self.config.controller.angular_samples)
        grid_v, grid_w = np.meshgrid(linear, angular, indexing="ij")
        return grid_v.ravel(), grid_w.ravel()

    def _rollout(self, linear: Floats, angular: Floats) -> tuple[Floats, Floats, Floats]:
        """Positions and headings along each constant-velocity arc, shape (samples, steps)."""
        t = self._times[None, :]
        v, w = linear[:, None], angular[:, None]
        heading = w * t
        turning = np.abs(w) > 1e-6
        radius = np.where(turning, v / np.where(turning, w, 1.0), 0.0)
        xs = np.where(turning, radius * np.sin(heading), v * t)
        ys = np.where(turning, radius * (1 - np.cos(heading)), 0.0)
        return xs, ys, heading

    def _cost(
        self, x: Floats, y: Floats, heading: Floats, carrot: Point, clear: Floats, v: Floats
    ) -> Floats:
        dx, dy = carrot[0] - x, carrot[1] - y
        distance = np.hypot(dx, dy)
        off = np.arctan2(dy, dx) - heading
        facing = np.where(distance < 0.05, 0.0, np.abs(np.arctan2(np.sin(off), np.cos(off))))
        crowding = np.clip(0.5 - clear, 0.0, None)
        return distance + 0.2 * facing + 2.0 * crowding - 0.2 * v

    def _turn_toward(self, carrot: Point) -> Command:
        bearing = math.atan2(carrot[1], carrot[0])
        return 0.0, _clamp(1.5 * bearing, self.config.body.max_angular)


# --- driving one leg -------------------------------------------------------------------


class DriveState(Enum):
    MOVING = "moving"
    ARRIVED = "arrived"
    FAILED = "failed"


@dataclass(frozen=True)
class Drive:
    """A tick's command (None: the robot's own navigation stack drives, leave it be)."""

    command: Command | None
    state: DriveState = DriveState.MOVING
    reason: str = ""


class LegDriver(Protocol):
    """What drives one leg at a time: ``Driver``, or a robot's own navigation stack."""

    @property
    def path(self) -> Sequence[Point]:
        """The current global plan, in the map frame."""
        ...

    @property
    def plan_version(self) -> int:
        """Changes whenever ``path`` does."""
        ...

    def drive(
        self,
        target: Pose,
        submap: SubMap | None,
        pose: Pose,
        velocity: Command,
        obstacles: LocalObstacles,
        seconds: float,
        odom: Pose = (0.0, 0.0, 0.0),
    ) -> Drive: ...

    def clear(self) -> None:
        """Forget the target and the plan (a navigation stack's goal is cancelled)."""

    def hold(self) -> Command | None:
        """Stand still for now, keeping the target: the command that does it."""
        ...

    def idle(self) -> Command | None:
        """The command with no goal at all (None: send nothing)."""
        ...


@dataclass
class _Progress:
    """How the current target is going: best distance so far and since when."""

    best: float = math.inf
    since: float = 0.0
    blocked_since: float | None = None
    replans: int = 0
    planned_at: float = -math.inf


class Driver:
    """Drives to one target pose at a time (see the module's docstring).

    ``path`` is the current global plan (map frame), ``plan_version`` grows when it
    changes. A target with no sub-map (a lost robot, driving by sight) gets a straight
    path: the controller still keeps clear of what the laser sees.
    """

    def __init__(self, config: RobotConfig | None = None) -> None:
        self.config = config or RobotConfig()
        self.tuning = self.config.controller
        self.controller = DynamicWindow(self.config)
        self.teb = TimedElasticBand(self.config) if self.config.local_planner == "teb" else None
        self._band_plan = 0  # the plan_version the band follows
        self.path: list[Point] = []
        self.plan_version = 0
        self._target: Pose | None = None
        self._submap: SubMap | None = None
        self._index = 0
        self._aligning = False
        self._progress = _Progress()

    def clear(self) -> None:
        """Forget the target and the plan."""
        if self.path:
            self.plan_version += 1
        self.path, self._target, self._submap = [], None, None
        self._aligning = False

    def hold(self) -> Command:
        """A stop; the target and plan stand."""
        return STOP

    def idle(self) -> Command:
        """A stop every tick: the body's own watchdog stops it too, but say so."""
        return STOP

    def drive(
        self,
        target: Pose,
        submap: SubMap | None,
        pose: Pose,
        velocity: Command,
        obstacles: LocalObstacles,
        seconds: float,
        odom: Pose = (0.0, 0.0, 0.0),
    ) -> Drive:
        """One command toward ``target`` from ``pose`` at ``velocity``; ``odom`` (the
        odometry pose) lets the TEB planner track what moves."""
        if self._retargeted(target, submap):
            failure = self._plan(target, submap, pose, seconds, obstacles=None)
            if failure:
                return Drive(STOP, DriveState.FAILED, failure)
        distance = math.dist(pose[:2], target[:2])
        # Hysteresis: once there, small drifts while turning do not restart the approach.
        if distance <= self.tuning.xy_tolerance:
            self._aligning = True
        elif distance > 3 * self.tuning.xy_tolerance:
            self._aligning = False
        if self._aligning:
            return self._align(pose, target)
        return self._follow(pose, velocity, obstacles, seconds, distance, odom)

    # --- planning ------------------------------------------------------------------------

    def _retargeted(self, target: Pose, submap: SubMap | None) -> bool:
        """Whether the target or the map changed enough to plan afresh."""
        previous = self._target
        moved = previous is None or math.dist(previous[:2], target[:2]) > RETARGET
        changed = moved or submap is not self._submap
        if changed:
            self._progress = _Progress()
            self._aligning = False
        if not moved and self.path:
            self._target = target  # a small move: the path's end follows, no new plan
            self.path[-1] = target[:2]
        return changed

    def _plan(
        self,
        target: Pose,
        submap: SubMap | None,
        pose: Pose,
        seconds: float,
        obstacles: Floats | None,
    ) -> str:
        """Plan from ``pose`` to ``target`` (around ``obstacles``, map-frame points, when
        given); returns why it failed, or ''."""
        self._target, self._submap, self._index = target, submap, 0
        self._progress.since = self._progress.planned_at = seconds
        path = [pose[:2], target[:2]]
        if submap is not None:
            costmap = self._costmap(submap, obstacles)
            try:
                path = [*plan_on(costmap, pose[:2], target[:2])[:-1], target[:2]]
            except OutOfMapError as error:
                if error.which == "goal":
                    return str(error)
                # Standing outside the sub-map's window (just entered it): go straight in.
            except PlanningError as error:
                return str(error)
        self.path = path
        self.plan_version += 1
        return ""

    def _costmap(self, submap: SubMap, obstacles: Floats | None) -> Costmap:
        """``submap`` inflated for this robot, with ``obstacles`` (map-frame points) added."""
        radius, planner = self.config.planning_radius, self.config.planner
        if obstacles is None:
            return submap.costmap(radius, planner)
        return submap.costmap_with(obstacles, radius, planner)

    # --- following -----------------------------------------------------------------------

    def _follow(
        self,
        pose: Pose,
        velocity: Command,
        obstacles: LocalObstacles,
        seconds: float,
        distance: float,
        odom: Pose,
    ) -> Drive:
        carrot = self._carrot(pose)
        if self._path_obstructed(pose, obstacles, seconds):
            # No way round what is seen (a person in a doorway): keep the path, they move.
            self._replan_around(obstacles, pose, seconds)
            carrot = self._carrot(pose)
        local = compose(inverse(pose), (*carrot, 0.0))
        bearing = math.atan2(local[1], local[0])
        if abs(bearing) > self.tuning.turn_in_place:
            command = (0.0, _clamp(1.5 * bearing, 1.0))
        else:
            # Slow enough to stop at the target within the braking limit, with a margin.
            cap = math.sqrt(2 * self.config.body.linear_accel * distance) * 0.7
            if self.teb is None:
                toward = (local[0], local[1])
                choice = self.controller.choose(velocity, toward, obstacles, cap, odom, seconds)
            else:
                choice = self._band_choice(pose, odom, velocity, obstacles, cap, seconds)
            self._note_blocked(choice.blocked, seconds)
            command = choice.command
        return self._after(Drive(command), pose, obstacles, seconds, distance)

    def _band_choice(
        self,
        pose: Pose,
        odom: Pose,
        velocity: Command,
        obstacles: LocalObstacles,
        cap: float,
        seconds: float,
    ) -> Choice:
        """The TEB planner's command along the next ``teb.horizon`` metres of the path."""
        assert self.teb is not None
        if self.plan_version != self._band_plan:
            self.teb.reset()  # a new global path: the old band may cross what it avoids
            self._band_plan = self.plan_version
        path, index = self.path, self._index
        start = _projection(pose[:2], path[index], path[index + 1]) if len(path) > 1 else path[0]
        local = local_path(path, start, index, pose, self.config.teb.horizon)
        final = bool(np.allclose(local[-1], transform(inverse(pose), np.array([path[-1]]))[0]))
        band = self.teb.choose(
            local, heading_at_end(local), final, velocity, obstacles.points, odom, seconds, cap
        )
        return Choice(band.command, band.blocked)

    def _after(
        self, drive: Drive, pose: Pose, obstacles: LocalObstacles, seconds: float, distance: float
    ) -> Drive:
        """Watch progress: replan around obstacles when blocked or stuck; give up after
        ``MAX_REPLANS`` in a row with no progress between them."""
        progress = self._progress
        if distance < progress.best - PROGRESS:
            # Getting on: earlier blockages (people who have since moved) no longer count.
            progress.best, progress.since, progress.replans = distance, seconds, 0
        since_blocked = progress.blocked_since
        blocked = since_blocked is not None and seconds - since_blocked >= BLOCKED_REPLAN
        if not blocked and seconds - progress.since < STUCK_AFTER:
            return drive
        if progress.replans >= MAX_REPLANS:
            return Drive(STOP, DriveState.FAILED, "blocked: no way through")
        progress.replans += 1
        progress.blocked_since = None
        failure = self._replan_around(obstacles, pose, seconds)
        return Drive(STOP) if failure else drive  # no way round yet: wait, and count it

    def _replan_around(self, obstacles: LocalObstacles, pose: Pose, seconds: float) -> str:
        """Plan again with the laser's near returns on the grid; why it failed, or ''."""
        assert self._target is not None
        seen = _in_map_frame(obstacles.points, pose)
        return self._plan(self._target, self._submap, pose, seconds, seen)

    def _path_obstructed(self, pose: Pose, obstacles: LocalObstacles, seconds: float) -> bool:
        """Whether the next ``LOOK_AHEAD`` metres of a planned path pass nearer a laser
        return than the robot may (checked at most every ``REPLAN_INTERVAL``)."""
        if self._submap is None or seconds - self._progress.planned_at < REPLAN_INTERVAL:
            return False
        ahead = [
            _along(self.path, self._index, pose[:2], d) for d in np.arange(0.1, LOOK_AHEAD, 0.1)
        ]
        local = np.array([compose(inverse(pose), (x, y, 0.0))[:2] for x, y in ahead])
        clear = obstacles.clearance(local[:, 0], local[:, 1])
        return bool((clear < self.config.body.radius + self.tuning.safety).any())

    def _note_blocked(self, blocked: bool, seconds: float) -> None:
        progress = self._progress
        if not blocked:
            progress.blocked_since = None
        elif progress.blocked_since is None:
            progress.blocked_since = seconds

    def _carrot(self, pose: Pose) -> Point:
        """The point ``lookahead`` metres along the path past the point nearest the robot
        (searched from the last one found, so the robot never turns back along it)."""
        path = self.path
        best, best_distance = self._index, math.inf
        for index in range(self._index, len(path) - 1):
            distance = _segment_distance(pose[:2], path[index], path[index + 1])
            if distance < best_distance - 1e-9:
                best, best_distance = index, distance
        self._index = best
        return _along(path, best, pose[:2], self.tuning.lookahead)

    def _align(self, pose: Pose, target: Pose) -> Drive:
        """At the target: turn on the spot to its heading, then report arrival."""
        error = wrap(target[2] - pose[2])
        if abs(error) <= self.tuning.yaw_tolerance:
            return Drive(STOP, DriveState.ARRIVED)
        return Drive((0.0, _clamp(2.0 * error, 1.0)))


def _in_map_frame(points: Floats, pose: Pose) -> Floats:
    """Robot-frame ``points`` within ``MARK_RANGE``, in the map frame."""
    near = points[np.hypot(points[:, 0], points[:, 1]) <= MARK_RANGE]
    return transform(pose, near)


def _segment_distance(p: Point, a: Point, b: Point) -> float:
    return math.dist(p, _projection(p, a, b))


def _projection(p: Point, a: Point, b: Point) -> Point:
    dx, dy = b[0] - a[0], b[1] - a[1]
    length2 = dx * dx + dy * dy
    along = 0.0 if length2 == 0 else ((p[0] - a[0]) * dx + (p[1] - a[1]) * dy) / length2
    t = max(0.0, min(1.0, along))
    return a[0] + t * dx, a[1] + t * dy


def _along(path: Sequence[Point], index: int, position: Point, lookahead: float) -> Point:
    """The point ``lookahead`` metres along ``path`` from the projection of ``position``
    on segment ``index``; the path's end if it is nearer."""
    if len(path) == 1:
        return path[0]
    point, left = _projection(position, path[index], path[index + 1]), lookahead
    for nxt in path[index + 1 :]:
        step = math.dist(point, nxt)
        if step >= left:
            f = left / step
            return point[0] + f * (nxt[0] - point[0]), point[1] + f * (nxt[1] - point[1])
        point, left = nxt, left - step
    return path[-1]


def _clamp(value: float, limit: float) -> float:
    return max(-limit, min(limit, value))


# --- goals, legs and driving together --------------------------------------------------


class Navigator:
    """The robot's navigation: goals from ``/r/goal``, legs from the supervisor, commands
    from the driver, statuses on the board."""

    def __init__(
        self,
        supervisor: MapsSupervisor,
        config: RobotConfig | None = None,
        driver: LegDriver | None = None,
    ) -> None:
        self.supervisor = supervisor
        self.driver: LegDriver = driver or Driver(config)
        self.board = GoalBoard()

    def set_goal(self, map_id: str, pose: Pose, seconds: float) -> None:
        """A new goal (pose in sub-map ``map_id`` of this building); preempts the last."""
        destination = Destination.parse(map_id, pose)
        if destination is None:
            self.reject(f"'{map_id}' is not a Map ID (building/map)", seconds)
            return
        self.board.start(seconds)
        self.supervisor.set_destination(destination)
        self.driver.clear()

    def reject(self, reason: str, seconds: float) -> None:
        """A goal that cannot be pursued: it preempts the last, then ends REJECTED with
        ``reason`` (as an actionlib server rejects a goal it cannot accept)."""
        self.board.start(seconds)
        self._end(GoalStatus.REJECTED, reason)

    def cancel(self) -> bool:
        """Cancel the active goal (PREEMPTED); False if there was none."""
        return self._end(GoalStatus.PREEMPTED, "cancelled")

    def step(
        self, pose: Pose, odom: Pose, velocity: Command, obstacles: LocalObstacles, seconds: float
    ) -> Command | None:
        """This tick's command (the driver's ``idle`` without an active goal; None: the
        robot's own navigation stack drives)."""
        if self.board.active is None:
            return self.driver.idle()
        leg = self.supervisor.leg(pose, odom, seconds)
        self.board.describe(leg.text)
        if leg.kind is LegKind.FAIL:
            self._end(GoalStatus.ABORTED, leg.text)
            return STOP
        if leg.kind is LegKind.SEARCH:
            self.driver.clear()
            return 0.0, SEARCH_RATE
        if leg.kind is LegKind.HOLD or leg.target is None:
            return self.driver.hold()
        return self._drive(leg, pose, odom, velocity, obstacles, seconds)

    def _drive(
        self,
        leg: Leg,
        pose: Pose,
        odom: Pose,
        velocity: Command,
        obstacles: LocalObstacles,
        seconds: float,
    ) -> Command | None:
        assert leg.target is not None
        drive = self.driver.drive(leg.target, leg.submap, pose, velocity, obstacles, seconds, odom)
        if drive.state is DriveState.FAILED:
            self._end(GoalStatus.ABORTED, drive.reason)
        elif drive.state is DriveState.ARRIVED and leg.kind is LegKind.FINAL:
            self._end(GoalStatus.SUCCEEDED, "arrived")
        elif drive.state is DriveState.ARRIVED:
            self.supervisor.arrived(seconds)
        elif drive.reason:  # a navigation stack's feedback on the leg
            self.board.describe(f"{leg.text} ({drive.reason})")
        return drive.command

    def _end(self, status: GoalStatus, text: str) -> bool:
        ended = self.board.finish(status, text)
        self.supervisor.set_destination(None)
        self.driver.clear()
        return ended
