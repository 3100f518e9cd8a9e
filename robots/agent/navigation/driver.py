"""``Driver`` drives to one target pose: A* on the current sub-map's inflated grid
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
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from cloudnav_core.params import RobotConfig
from cloudnav_core.se2 import Floats, Point, Pose, compose, inverse, transform, wrap
from maps.domain.planning import Costmap, OutOfMapError, PlanningError, plan_on
from robots.agent.navigation.clearance import LocalObstacles
from robots.agent.navigation.commands import STOP, Command, clamp
from robots.agent.navigation.dynamic_window import Choice, DynamicWindow
from robots.agent.navigation.legs import Drive, DriveState
from robots.agent.navigation.paths import distance_to_segment, point_along, projection_on
from robots.agent.supervisor.submaps import SubMap
from robots.agent.teb import TimedElasticBand, heading_at_end, local_path

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
BLIND_HORIZON = 0.6
"""Seconds of a command's motion whose swept floor must have been seen free, for a robot
that sees only ahead (longer than it takes to brake from full speed)."""
BLIND_EDGE = np.radians(np.linspace(-50.0, 50.0, 11))
"""Bearings of the footprint's leading edge, from the direction of motion, checked."""
LOOK_TURN = 0.6
"""rad/s: the turn of a robot held back by the blind-side guard, toward what it may not
enter, to look at it."""


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
            command = (0.0, clamp(1.5 * bearing, 1.0))
        else:
            # Slow enough to stop at the target within the braking limit, with a margin.
            cap = math.sqrt(2 * self.config.body.linear_accel * distance) * 0.7
            if self.teb is None:
                toward = (local[0], local[1])
                choice = self.controller.choose(velocity, toward, obstacles, cap, odom, seconds)
            else:
                choice = self._band_choice(pose, odom, velocity, obstacles, cap, seconds)
            self._note_blocked(choice.blocked, seconds)
            command = self._blind_guard(choice.command, obstacles)
        return self._after(Drive(command), pose, obstacles, seconds, distance)

    def _blind_guard(self, command: Command, obstacles: LocalObstacles) -> Command:
        """A robot that sees only ahead moves only where it may (``LocalObstacles``'s
        ``may_enter``: near a person it saw walking lately, onto floor it saw free): the
        linear speed is halved, down to none, until the footprint's leading edge over the
        next ``BLIND_HORIZON`` seconds stays there. Held back, it turns to look at the floor
        it may not enter (a person who stopped beside it, out of its camera's view, is
        not driven into). Backing away (from someone walking into it) is never held back."""
        linear, angular = command
        if obstacles.may_enter is None or linear <= 0.0:
            return command
        edge = self._leading_edge(linear, angular)
        allowed = obstacles.may_enter(edge)
        if allowed.all():
            return command
        for share in (0.5, 0.25):
            if obstacles.may_enter(self._leading_edge(linear * share, angular)).all():
                return linear * share, angular
        if abs(angular) >= LOOK_TURN:
            return 0.0, angular
        unseen = edge[~allowed]
        return 0.0, math.copysign(LOOK_TURN, float(np.mean(np.arctan2(unseen[:, 1], unseen[:, 0]))))

    def _leading_edge(self, linear: float, angular: float) -> Floats:
        """Robot-frame points of the footprint's edge (radius plus the controller's safety)
        ahead of its motion at ``(linear, angular)`` over ``BLIND_HORIZON``, less those
        within the footprint where it stands."""
        reach = self.config.body.radius + self.tuning.safety
        period = self.config.period
        times = np.arange(period, BLIND_HORIZON + period / 2, period)
        heading = angular * times
        if abs(angular) > 1e-6:
            x = linear / angular * np.sin(heading)
            y = linear / angular * (1.0 - np.cos(heading))
        else:
            x, y = linear * times, np.zeros_like(times)
        motion = heading[:, None] + BLIND_EDGE[None, :] + (0.0 if linear > 0 else math.pi)
        edge = np.stack(
            [x[:, None] + reach * np.cos(motion), y[:, None] + reach * np.sin(motion)], -1
        )
        points = edge.reshape(-1, 2)
        return np.asarray(points[np.hypot(points[:, 0], points[:, 1]) > reach + 1e-6], np.float64)

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
        start = projection_on(pose[:2], path[index], path[index + 1]) if len(path) > 1 else path[0]
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
            point_along(self.path, self._index, pose[:2], d)
            for d in np.arange(0.1, LOOK_AHEAD, 0.1)
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
            distance = distance_to_segment(pose[:2], path[index], path[index + 1])
            if distance < best_distance - 1e-9:
                best, best_distance = index, distance
        self._index = best
        return point_along(path, best, pose[:2], self.tuning.lookahead)

    def _align(self, pose: Pose, target: Pose) -> Drive:
        """At the target: turn on the spot to its heading, then report arrival."""
        error = wrap(target[2] - pose[2])
        if abs(error) <= self.tuning.yaw_tolerance:
            return Drive(STOP, DriveState.ARRIVED)
        return Drive((0.0, clamp(2.0 * error, 1.0)))


def _in_map_frame(points: Floats, pose: Pose) -> Floats:
    """Robot-frame ``points`` within ``MARK_RANGE``, in the map frame."""
    near = points[np.hypot(points[:, 0], points[:, 1]) <= MARK_RANGE]
    return transform(pose, near)
