"""The local controller: the dynamic window approach (``DynamicWindow``) on what the laser
sees, and its ``Choice`` of command."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from cloudnav_core.params import RobotConfig
from cloudnav_core.se2 import Floats, Point, Pose
from robots.agent.navigation.clearance import CELL, Clearance, LocalObstacles
from robots.agent.navigation.commands import STOP, Command, clamp
from robots.agent.tracking import ObstacleTracker


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
        clearance = Clearance.of(self.tracker.update(obstacles.points, odom, seconds), obstacles)
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
        self, velocity: Command, carrot: Point, clearance: Clearance, can_turn: bool
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

    def _backwards(self, velocity: Command, clearance: Clearance, standing: int) -> Command | None:
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
        return 0.0, clamp(1.5 * bearing, self.config.body.max_angular)
