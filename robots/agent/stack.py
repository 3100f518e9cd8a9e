"""The Maps Supervisor inside a robot's own navigation stack (``NavigationStack`` of
``robots.agent.hardware``: ROS move_base with AMCL and a map server, or Nav2).

- ``StackPoseTracker`` is the pose estimate: every sub-map entered goes to the stack
  (``set_map``: ``/map``, a map server's ``load_map``), every reset (a tag read, a marker
  seen near, an operator's initial pose) to its localisation (``set_initial_pose`` with
  the tag's covariance), and the pose is the stack's own (AMCL, tf) once it has
  localised after the last reset; odometry from that reset until then.
- ``StackDriver`` drives each leg the supervisor chooses (to the tag leading on, then to
  the goal) by sending the stack a goal, and reports what the stack says of it. A lost
  robot (no sub-map yet, so nothing on ``/map``) approaches a marker by sight with the
  agent's own ``Driver`` on ``cmd_vel``, as a search turns on ``cmd_vel``.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from cloudnav_core.params import RobotConfig
from cloudnav_core.se2 import Point, Pose
from robots.agent.hardware import NavigationStack, StackGoal
from robots.agent.navigation.clearance import LocalObstacles
from robots.agent.navigation.commands import STOP, Command
from robots.agent.navigation.driver import RETARGET, Driver
from robots.agent.navigation.legs import Drive, DriveState
from robots.agent.robot import PoseTracker
from robots.agent.supervisor.submaps import SubMap

logger = logging.getLogger(__name__)


class StackPoseTracker(PoseTracker):
    """The pose estimate of a robot whose navigation stack localises it (no particle
    filter of the agent's own)."""

    def __init__(self, stack: NavigationStack) -> None:
        super().__init__(None)
        self.stack = stack
        self.map_id: str | None = None  # the sub-map the stack holds
        self._covariance: NDArray[np.float64] = np.diag([0.05, 0.05, 0.02])

    def reset(self, pose: Pose, covariance: NDArray[np.float64], at_odom: Pose) -> None:
        super().reset(pose, covariance, at_odom)
        self._covariance = np.asarray(covariance, dtype=np.float64)
        if self.map_id is not None:
            self.stack.set_initial_pose(self.map_id, super().pose(), self._covariance)

    def set_map(self, submap: SubMap) -> None:
        """Hand ``submap`` to the stack and place the robot in it again: a map server and
        AMCL start a new map from their last initial pose, not from where the robot is."""
        here = self.pose()
        self.map_id = submap.map_id
        self.stack.set_map(submap.map_id, submap.grid, submap.resolution, submap.origin)
        if self.localised:
            self.stack.set_initial_pose(submap.map_id, here, self._covariance)

    def pose(self) -> Pose:
        localised = self.stack.pose() if self.localised else None
        return super().pose() if localised is None else localised


class StackDriver:
    """Drives legs through ``stack`` (see the module's docstring); a ``LegDriver``."""

    def __init__(self, stack: NavigationStack, config: RobotConfig | None = None) -> None:
        self.stack = stack
        self.by_sight = Driver(config)
        self._sent: tuple[str, Pose] | None = None  # the goal the stack drives to
        self._switches = 0  # between the stack's plan and the one by sight

    @property
    def path(self) -> Sequence[Point]:
        return self.stack.plan()[1] if self._sent is not None else self.by_sight.path

    @property
    def plan_version(self) -> int:
        return self.stack.plan()[0] + self.by_sight.plan_version + self._switches

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
        """Send ``target`` to the stack when it is new (or moved ``RETARGET``), then
        follow the stack's goal: None as the command while it drives."""
        if submap is None:
            self._withdraw()
            return self.by_sight.drive(target, None, pose, velocity, obstacles, seconds, odom)
        was_by_sight = bool(self.by_sight.path)
        self.by_sight.clear()
        if self._retargeted(submap.map_id, target):
            logger.info("goal for the stack: %s (%.2f, %.2f, %.2f)", submap.map_id, *target)
            self.stack.send_goal(submap.map_id, target)
            self._sent = (submap.map_id, target)
            self._switches += 1
            return Drive(STOP if was_by_sight else None)  # driving by sight ends in a stop
        return self._followed(target)

    def _retargeted(self, map_id: str, target: Pose) -> bool:
        sent = self._sent
        return sent is None or sent[0] != map_id or math.dist(sent[1][:2], target[:2]) > RETARGET

    def _followed(self, target: Pose) -> Drive:
        state = self.stack.goal_state()
        if state is StackGoal.SUCCEEDED:
            return Drive(None, DriveState.ARRIVED)
        if state is StackGoal.FAILED:
            reason = f"the navigation stack could not reach ({target[0]:.2f}, {target[1]:.2f})"
            return Drive(STOP, DriveState.FAILED, reason)
        if state is StackGoal.NONE:  # cancelled from outside (another client): send again
            self._sent = None
        return Drive(None, reason=self.stack.progress())

    def _withdraw(self) -> None:
        """Cancel the stack's goal, if one was sent."""
        if self._sent is not None:
            self._sent = None
            self._switches += 1
            self.stack.cancel()

    def clear(self) -> None:
        self._withdraw()
        self.by_sight.clear()

    def hold(self) -> Command:
        """The stack's goal is cancelled (it is sent again when driving resumes); a stop."""
        self._withdraw()
        return STOP

    def idle(self) -> None:
        """Nothing: without a goal, the robot is left to whatever else drives it."""
        return None
