"""Runs the missions of the robots this process serves: sends each goal, and moves on when
the robot reports it reached it, or when the goal's time limit passes (``late``: the
waypoint is skipped or the mission paused, as the mission says).

What robots report is read on the relay's path in memory (``status``); once a tick the
runner records the outcomes and collects the goals due in one database call, off the loop.
"""

from __future__ import annotations

import asyncio
import logging
import time
from collections.abc import Awaitable, Callable, Mapping
from typing import Any

from channels.db import database_sync_to_async

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
    ) -> None:
        self.send = send
        self.robots = robots
        self.place = place
        self.late = late
        self.interval = interval
        self.clock = clock
        self._sent: dict[str, tuple[Goal, float]] = {}  # robot -> (goal, when sent)
        self._outcomes: dict[int, str] = {}
        self._task: asyncio.Task[None] | None = None

    def status(self, robot: str, msg: Mapping[str, Any]) -> None:
        """A robot's GoalStatusArray: the outcome of the mission goal it was sent, if over."""
        sent = self._sent.get(robot)
        statuses = msg.get("status_list") or []
        if sent is None or not statuses or self.clock() - sent[1] < GRACE_S:
            return
        latest = statuses[-1]
        code = latest.get("status") if isinstance(latest, Mapping) else None
        if code == SUCCEEDED:
            self._outcomes[sent[0].mission] = missions.REACHED
        elif code in FAILED:
            reason = storable_text(str(latest.get("text") or "no reason"))
            self._outcomes[sent[0].mission] = f"goal {FAILED[code]}: {reason}"
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
                self._sent[goal.robot] = (placed, self.clock())
                self.send(placed)

    def _late(self) -> list[Goal]:
        """The goals sent whose time limit passed: their outcome is TIMED_OUT."""
        now = self.clock()
        late = [
            goal
            for goal, sent_at in self._sent.values()
            if goal.time_limit > 0 and now - sent_at > goal.time_limit
        ]
        for goal in late:
            del self._sent[goal.robot]
            self._outcomes[goal.mission] = missions.TIMED_OUT
        return late


def _tick(robots: set[str], outcomes: dict[int, str]) -> tuple[list[Goal], set[int]]:
    recorded = missions.record_outcomes(outcomes)
    return missions.goals_due(robots), recorded
