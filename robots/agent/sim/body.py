"""A simulated differential-drive robot: velocity limits, collisions, noisy odometry.

The body lives on a simulated clock advanced in fixed steps (``rate_hz``, 50 Hz by
default), so a run is a pure function of its commands and its seed. ``command`` sets the
wanted velocity, clamped to the limits; the body reaches it within the acceleration limits.
Like a TurtleBot's base, it stops by itself (decelerating at its limits) when no command
arrived for ``watchdog`` seconds.

Odometry integrates the motion the wheels report: the true motion with a systematic
scale error and a random error whose variance grows in proportion to the distance and
angle travelled, so drift does not depend on the step rate. ``odom_pose`` starts at
``(0, 0, 0)`` in the odometry frame, as ROS odometry does.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from cloudnav_core.messages import Odometry, odometry
from cloudnav_core.params import BodyLimits
from cloudnav_core.se2 import Pose, wrap
from robots.agent.sim.crowd import NO_DISCS, Movers, disc_clearance
from robots.agent.sim.world import World


@dataclass(frozen=True)
class OdometryNoise:
    """Odometry error model.

    ``*_sigma`` is the standard deviation of the error accumulated over one unit of motion
    (variance grows linearly with motion): ``translation_sigma`` metres per metre driven,
    ``rotation_sigma`` radians of heading per radian turned, ``heading_per_metre`` radians
    of heading per metre driven. ``*_scale`` are systematic factors (wheel radius and
    wheel base errors); 1.0 is perfect calibration.
    """

    translation_sigma: float = 0.02
    rotation_sigma: float = 0.03
    heading_per_metre: float = 0.01
    linear_scale: float = 1.0
    angular_scale: float = 1.0


EXACT_ODOMETRY = OdometryNoise(0.0, 0.0, 0.0)


class DiffDriveBody:
    """One robot's base in ``world``, starting at ``pose`` (map frame) at time 0."""

    def __init__(
        self,
        world: World,
        pose: Pose,
        *,
        limits: BodyLimits | None = None,
        noise: OdometryNoise | None = None,
        rate_hz: float = 50.0,
        watchdog: float = 0.5,
        seed: int = 0,
        others: Movers | None = None,
    ) -> None:
        if rate_hz < 20:
            raise ValueError("the body integrates at 20 Hz or more")
        self.world = world
        self.others = others or (lambda: NO_DISCS)  # people and robots that bump it too
        self.limits = limits or BodyLimits()
        self.noise = noise or OdometryNoise()
        self.dt = 1.0 / rate_hz
        self.watchdog = watchdog
        self.rng = np.random.default_rng(seed)
        self.time = 0.0
        self.pose: Pose = pose
        self.odom_pose: Pose = (0.0, 0.0, 0.0)
        self.velocity = (0.0, 0.0)  # true (linear, angular)
        self.bumped = False  # the last step's translation was blocked
        # Variance added along the way by the random errors, for the message's covariance
        # (it leaves out the position error that heading error causes later on).
        self.odom_variance = (0.0, 0.0)
        self._wanted = (0.0, 0.0)
        self._last_command = -math.inf

    @property
    def radius(self) -> float:
        return self.limits.radius

    def command(self, linear: float, angular: float) -> None:
        """Set the wanted velocity (a ``cmd_vel``), clamped to the limits, at ``self.time``."""
        lim = self.limits
        self._wanted = (_clamp(linear, lim.max_linear), _clamp(angular, lim.max_angular))
        self._last_command = self.time

    def advance(self, seconds: float) -> None:
        """Run whole steps until ``seconds`` more of simulated time have passed."""
        for _ in range(round(seconds / self.dt)):
            self.step()

    def step(self) -> None:
        """Advance one fixed step: watchdog, acceleration limits, motion, odometry."""
        if self.time - self._last_command >= self.watchdog - 1e-9:
            self._wanted = (0.0, 0.0)
        self.velocity = self._accelerated()
        moved = self._move(*self.velocity)
        self._integrate_odometry(*moved)
        self.time += self.dt

    def _accelerated(self) -> tuple[float, float]:
        """The velocity after one step of accelerating toward the wanted one."""
        lim = self.limits
        linear = _approach(self.velocity[0], self._wanted[0], lim.linear_accel * self.dt)
        angular = _approach(self.velocity[1], self._wanted[1], lim.angular_accel * self.dt)
        return linear, angular

    def _move(self, linear: float, angular: float) -> tuple[float, float]:
        """Move the true pose by one step (exact arc); return ``(distance, turn)`` done.

        A translation that would take the footprint into a solid cell is not made and the
        linear velocity drops to zero: the robot stops at the wall and may still turn, or
        back away.
        """
        x, y, yaw = self.pose
        distance, turn = linear * self.dt, angular * self.dt
        new_x, new_y = _arc_end(x, y, yaw, distance, turn)
        self.bumped = distance != 0 and self._blocked((x, y), (new_x, new_y))
        if self.bumped:
            new_x, new_y, distance = x, y, 0.0
            self.velocity = (0.0, angular)
        self.pose = (new_x, new_y, wrap(yaw + turn))
        return distance, turn

    def _blocked(self, start: tuple[float, float], end: tuple[float, float]) -> bool:
        """Whether moving from ``start`` to ``end`` touches a wall, a person or another
        robot, or moves nearer one while already touching (a robot placed too close, or
        walked into, may still leave)."""
        radius = self.limits.radius
        after = self.world.clearance(*end, radius)
        if after < radius and after <= self.world.clearance(*start, radius):
            return True
        others = self.others()
        after = disc_clearance(*end, others)
        return after < radius and after <= disc_clearance(*start, others)

    def _integrate_odometry(self, distance: float, turn: float) -> None:
        """Add the step's motion, as the wheels misreport it, to ``odom_pose``."""
        noise, travelled, turned = self.noise, abs(distance), abs(turn)
        distance = distance * noise.linear_scale + self._error(noise.translation_sigma, travelled)
        heading_var = noise.rotation_sigma**2 * turned + noise.heading_per_metre**2 * travelled
        turn = turn * noise.angular_scale + self._error(math.sqrt(heading_var), 1.0)
        x, y, yaw = self.odom_pose
        x, y = _arc_end(x, y, yaw, distance, turn)
        self.odom_pose = (x, y, wrap(yaw + turn))
        position_var, yaw_var = self.odom_variance
        position_var += noise.translation_sigma**2 * travelled
        self.odom_variance = (position_var, yaw_var + heading_var)

    def _error(self, sigma: float, motion: float) -> float:
        """A random error with variance ``sigma**2 * motion`` (0 without motion)."""
        if sigma == 0 or motion == 0:
            return 0.0
        return float(self.rng.normal(0.0, sigma * math.sqrt(motion)))

    def odometry_message(
        self,
        frame_id: str = "odom",
        child_frame_id: str = "base_footprint",
        seconds: float | None = None,
    ) -> Odometry:
        """``nav_msgs/Odometry`` of the odometry pose and the reported velocity, stamped
        ``seconds`` (wall-clock time, say), by default the simulated clock."""
        linear, angular = self.velocity
        noise = self.noise
        position_var, yaw_var = self.odom_variance
        return odometry(
            frame_id,
            child_frame_id,
            self.time if seconds is None else seconds,
            pose=self.odom_pose,
            pose_covariance=_variances(position_var, position_var, yaw_var),
            velocity=(linear * noise.linear_scale, angular * noise.angular_scale),
            velocity_covariance=_variances(1e-4, 1e-4, 1e-4),
        )


def _arc_end(x: float, y: float, yaw: float, distance: float, turn: float) -> tuple[float, float]:
    """End point of driving ``distance`` while turning by ``turn`` (a circular arc)."""
    if abs(turn) < 1e-9:
        return x + distance * math.cos(yaw), y + distance * math.sin(yaw)
    radius = distance / turn
    return (
        x + radius * (math.sin(yaw + turn) - math.sin(yaw)),
        y - radius * (math.cos(yaw + turn) - math.cos(yaw)),
    )


def _variances(x: float, y: float, yaw: float) -> tuple[tuple[float, float, float], ...]:
    """A 3x3 covariance over (x, y, yaw) with only these variances."""
    return (x, 0.0, 0.0), (0.0, y, 0.0), (0.0, 0.0, yaw)


def _approach(current: float, target: float, max_change: float) -> float:
    return current + _clamp(target - current, max_change)


def _clamp(value: float, limit: float) -> float:
    return max(-limit, min(limit, value))
