"""``Navigator`` joins goals, legs and driving for the Maps Supervisor: each tick the
supervisor says which leg comes next (search, approach a tag, the goal itself), the driver
(a ``LegDriver``) drives it, and the board records how the goal ends; the cloud's right of
way holds the robot at a spot until it is told to go."""

from __future__ import annotations

import math

from cloudnav_core.messages import GoalStatus, WaitOrder
from cloudnav_core.params import RobotConfig
from cloudnav_core.se2 import Pose
from robots.agent.navigation.clearance import LocalObstacles
from robots.agent.navigation.commands import STOP, Command
from robots.agent.navigation.driver import Driver
from robots.agent.navigation.goals import GoalBoard
from robots.agent.navigation.legs import DriveState, LegDriver
from robots.agent.supervisor.legs import Destination, Leg, LegKind
from robots.agent.supervisor.maps_supervisor import SEARCH_RATE, MapsSupervisor

# Metres from the spot the cloud gave where a robot giving way stops and waits.
AT_SPOT = 0.2


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
        self.waiting: WaitOrder | None = None  # the cloud's word to give way, if any
        self._at_spot = False

    @property
    def holding(self) -> bool:
        """True while the robot stands at the spot the cloud told it to wait at."""
        return self.waiting is not None and self._at_spot

    def give_way(self, order: WaitOrder | None) -> None:
        """The cloud's right of way: wait at ``order``'s spot (drive there, hold still) in
        its sub-map until told to go (None), then go on with the goal."""
        if order != self.waiting:
            self.waiting, self._at_spot = order, False

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
        if self._waits_in(leg):
            return self._wait(leg, pose, odom, velocity, obstacles, seconds)
        return self._drive(leg, pose, odom, velocity, obstacles, seconds)

    def _waits_in(self, leg: Leg) -> bool:
        order = self.waiting
        return order is not None and leg.submap is not None and leg.submap.map_id == order.map_id

    def _wait(
        self,
        leg: Leg,
        pose: Pose,
        odom: Pose,
        velocity: Command,
        obstacles: LocalObstacles,
        seconds: float,
    ) -> Command | None:
        """Drive to the spot the cloud gave and hold there (or hold where it stands when
        the spot cannot be reached) until told to go."""
        assert self.waiting is not None
        self.board.describe(f"{leg.text} (waiting for {self.waiting.waiting_for} to pass)")
        spot = self.waiting.spot
        if self._at_spot or math.dist(pose[:2], spot[:2]) <= AT_SPOT:
            self._at_spot = True  # there: it waits facing as it stands
            return self.driver.hold()
        drive = self.driver.drive(spot, leg.submap, pose, velocity, obstacles, seconds, odom)
        if drive.state is not DriveState.MOVING:
            self._at_spot = True
            return self.driver.hold()
        return drive.command

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
