"""Runs the missions of the robots this process serves: sends each goal, and moves on when
the robot reports it reached it, or when the goal's time limit passes (``late``: the
waypoint is skipped or the mission paused, as the mission says).

A time limit runs on the robot's own clock, read from the stamps of its goal statuses, as
a ROS node's timers run on ``/clock`` under ``use_sim_time``: a simulated robot running
at a quarter of real time gets its waypoint's whole limit in its own seconds. A robot
whose statuses carry no stamp is timed on the server's clock; one that says nothing for a
while has its clock taken to run on at the server's pace (``cloudnav_core.times.RobotClocks``,
shared with the stuck rule).

What robots report is read on the relay's path in memory (``status``); once a tick the
runner records the outcomes and collects the goals due in one database call, off the loop.
"""

from __future__ import annotations

import asyncio
import logging
import time
from collections.abc import Awaitable, Callable, Mapping
from dataclasses import dataclass
from typing import Any

from channels.db import database_sync_to_async

from cloudnav_core.times import RobotClocks
from cloudnav_django.batches import BatchInterrupted
from cloudnav_django.outage import REPORT
from robots import missions
from robots.missions import Goal
from telemetry.domain.storable import storable_text

logger = logging.getLogger(__name__)

# After a goal is sent, the statuses of the goal before it are not its outcome.
GRACE_S = 1.5
# actionlib_msgs/GoalStatus codes.
SUCCEEDED = 3
FAILED = {4: "aborted", 5: "rejected", 9: "lost"}


@dataclass(frozen=True)
class Sent:
    """A mission goal sent: when, on the server's clock and on the robot's (None: its
    statuses carried no stamp yet)."""

    goal: Goal
    at: float
    robot_at: float | None = None


class MissionRunner:
    """``place`` gives each goal due its spot among the other robots' (the fleet rule):
    the goal to send, or the reason it is refused, which pauses its mission. ``late`` is
    told of each goal not reached within its time limit (after its outcome is recorded)."""

    def __init__(
        self,
        send: Callable[[Goal], None],
        robots: Callable[[], set[str]],
        place: Callable[[Goal], Awaitable[Goal | str]],
        late: Callable[[Goal], Awaitable[None]],
        interval: float = 1.0,
        clock: Callable[[], float] = time.monotonic,
        robot_clocks: RobotClocks | None = None,
    ) -> None:
        self.send = send
        self.robots = robots
        self.place = place
        self.late = late
        self.interval = interval
        self.clock = clock
        self.robot_clocks = robot_clocks or RobotClocks(clock)
        self._sent: dict[str, Sent] = {}  # robot -> its mission goal sent
        self._outcomes: dict[int, str] = {}
        self._task: asyncio.Task[None] | None = None

    def status(self, robot: str, msg: Mapping[str, Any]) -> None:
        """A robot's GoalStatusArray: its time now, and the outcome of the mission goal it
        was sent, if over."""
        self.robot_clocks.heard(robot, msg)
        sent = self._sent.get(robot)
        statuses = msg.get("status_list") or []
        if sent is None or not statuses or self.clock() - sent.at < GRACE_S:
            return
        latest = statuses[-1]
        code = latest.get("status") if isinstance(latest, Mapping) else None
        if code == SUCCEEDED:
            self._outcomes[sent.goal.mission] = missions.REACHED
        elif code in FAILED:
            reason = storable_text(str(latest.get("text") or "no reason"))
            self._outcomes[sent.goal.mission] = f"goal {FAILED[code]}: {reason}"
        else:
            return
        del self._sent[robot]

    def ensure_running(self) -> None:
        if self._task is None or self._task.done():
            self._task = asyncio.get_running_loop().create_task(self.run())

    async def run(self) -> None:
        """Tick while this process serves robots."""
        while self.robots():
            await asyncio.sleep(self.interval)
            late = self._late()
            outcomes, self._outcomes = self._outcomes, {}
            try:
                goals, recorded = await database_sync_to_async(_tick)(self.robots(), outcomes)
            except BatchInterrupted as interrupted:
                REPORT.failed("mission ticks held back", interrupted)
                kept = {pk: outcomes[pk] for pk in interrupted.unwritten}
                self._outcomes = {**kept, **self._outcomes}
                continue
            except Exception:  # the outcomes were recorded: never twice (a waypoint skipped)
                logger.exception("the mission tick failed after recording its outcomes")
                continue
            for goal in late:
                if goal.mission in recorded:  # not paused or replaced meanwhile
                    await self.late(goal)
            for goal in goals:
                placed = await self.place(goal)
                if isinstance(placed, str):
                    self._outcomes[goal.mission] = placed
                    continue
                robot_at = self.robot_clocks.now(goal.robot)
                self._sent[goal.robot] = Sent(placed, self.clock(), robot_at)
                self.send(placed)

    def _late(self) -> list[Goal]:
        """The goals sent whose time limit passed: their outcome is TIMED_OUT."""
        late = [
            sent.goal
            for sent in self._sent.values()
            if 0 < sent.goal.time_limit < self._elapsed(sent)
        ]
        for goal in late:
            del self._sent[goal.robot]
            self._outcomes[goal.mission] = missions.TIMED_OUT
        return late

    def _elapsed(self, sent: Sent) -> float:
        """Seconds since ``sent``, on the robot's clock where its stamps tell it (a clock
        set back, as a restarted simulation's is, is not: the server's then)."""
        robot_now = self.robot_clocks.now(sent.goal.robot)
        if sent.robot_at is None or robot_now is None or robot_now < sent.robot_at:
            return self.clock() - sent.at
        return robot_now - sent.robot_at


def _tick(robots: set[str], outcomes: dict[int, str]) -> tuple[list[Goal], set[int]]:
    recorded = missions.record_outcomes(outcomes)
    return missions.goals_due(robots), recorded
