"""The fleet rule for stuck robots, on the server: when the event log raises
``robot_stuck`` for a robot connected here, decide at once (``maps.domain.stuck_rule``:
wait or replan), act, and if the same stuck spell lasts ``give_up_after`` seconds more,
abort; each choice is a ``fleet_rule`` event that says plainly what was chosen and why.
Seconds are counted as the stuck alert's are, on the robot's clock and the server's, the
shorter count (``EventDeriver.stuck_for``).
"""

from __future__ import annotations

import asyncio
from collections.abc import Awaitable, Callable
from dataclasses import replace

from maps.domain.stuck_rule import StuckAction, StuckCase, StuckResponse, give_up, respond
from telemetry.domain.events import EventDraft, Severity
from telemetry.events import EventLog
from telemetry.right_of_way import RightOfWay

# Seconds: a blocking robot that moved within this long is moving (out of the way).
MOVING_WITHIN_S = 5.0
# Seconds of the server's clock between looks at a stuck spell's length.
LOOK_EVERY_S = 1.0


class StuckRule:
    """Answers this process's stuck alerts (see the module)."""

    def __init__(
        self,
        events: EventLog,
        right_of_way: RightOfWay,
        give_up_after: float,
        resend: Callable[[str, str], bool],
        halt: Callable[[str], Awaitable[str]],
    ) -> None:
        self.give_up_after = give_up_after
        self._events = events
        self._right_of_way = right_of_way
        self._resend = resend  # (robot, why) -> sent again
        self._halt = halt
        self._tasks: set[asyncio.Task[None]] = set()

    def stuck(self, draft: EventDraft) -> None:
        """The event log raised ``draft`` (``robot_stuck``): respond now, and give up
        later if the spell goes on."""
        robot = draft.robot
        if robot is None:
            return
        case = self._case(robot, draft)
        response = respond(case, self.give_up_after)
        if response.action is StuckAction.REPLAN and not self._resend(robot, response.reason):
            response = respond(replace(case, can_resend=False), self.give_up_after)
        self._tell(robot, response)
        deriver = self._events.deriver
        since, held = deriver.stuck_since(robot), deriver.stuck_for(robot, self._events.clock())
        task = asyncio.get_running_loop().create_task(self._later(case, since, held))
        self._tasks.add(task)
        task.add_done_callback(self._tasks.discard)

    def _case(self, robot: str, draft: EventDraft) -> StuckCase:
        blocker = str(draft.data.get("blocker", "unknown"))
        why = draft.message.partition(": ")[2] or "blocked by an unknown obstacle or person"
        now = self._events.clock()
        return StuckCase(
            robot,
            blocker,
            why,
            giving_way=self._right_of_way.blocking(robot) is not None,
            blocker_moving=self._events.deriver.moved_within(blocker, MOVING_WITHIN_S, now),
        )

    async def _later(self, case: StuckCase, since: float | None, held: float) -> None:
        """Give up once the spell that began at ``since``, ``held`` seconds long when it was
        raised, has lasted ``give_up_after`` seconds more (``EventDeriver.stuck_for``'s count)."""
        deriver = self._events.deriver
        while True:
            await asyncio.sleep(min(LOOK_EVERY_S, self.give_up_after))
            if since is None or deriver.stuck_since(case.robot) != since:
                return  # moving again, goal over, or another spell
            lasted = deriver.stuck_for(case.robot, self._events.clock())
            if lasted >= held + self.give_up_after:
                break
        response = give_up(case, lasted)
        outcome = await self._halt(case.robot)
        self._tell(case.robot, response, f" (goal {outcome})")

    def _tell(self, robot: str, response: StuckResponse, after: str = "") -> None:
        severity = Severity.ERROR if response.action is StuckAction.ABORT else Severity.WARNING
        self._events.fleet_rule(robot, response.reason + after, response.action.value, severity)
