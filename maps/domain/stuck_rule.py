"""What the fleet does with a stuck robot (issue 28, point 3): wait, replan or abort, and
the sentence that says which and why.

A robot that made no progress for ``CLOUDNAV_STUCK_AFTER`` raises ``robot_stuck`` naming
what blocks it. At once the fleet rule decides:

- **wait** when the robot is giving way in a narrow place (right of way: it goes when
  the other is through), or when the robot blocking it is moving (it is getting out of
  the way), or when the server knows no goal to send again;
- **replan** when a standing robot or an unknown obstacle or person blocks it: its goal
  is sent again, so it plans afresh from where it stands, around what its laser sees;

and if the robot is still stuck ``give_up_after`` seconds later (the same stuck spell),
**abort**: the goal is cancelled and the robot halted, the reason said. Nothing here
imports Django.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum


class StuckAction(StrEnum):
    WAIT = "wait"
    REPLAN = "replan"
    ABORT = "abort"


@dataclass(frozen=True)
class StuckCase:
    """One stuck robot as the fleet sees it: ``blocker`` the robot in its way (or
    ``unknown``), ``why`` the alert's phrase for it; whether the robot is giving way in a
    narrow place, whether the blocking robot moved lately, whether a goal can be resent."""

    robot: str
    blocker: str
    why: str
    giving_way: bool = False
    blocker_moving: bool = False
    can_resend: bool = True


@dataclass(frozen=True)
class StuckResponse:
    action: StuckAction
    reason: str


def respond(case: StuckCase, give_up_after: float) -> StuckResponse:
    """What the fleet does at once with a robot that has just been found stuck."""
    then = f"it is aborted if still stuck {give_up_after:g} s from now"
    head = f"{case.robot} is stuck, {case.why}"
    if case.giving_way:
        return StuckResponse(StuckAction.WAIT, f"{head}: the fleet waits, its turn comes; {then}")
    if case.blocker != "unknown" and case.blocker_moving:
        return StuckResponse(
            StuckAction.WAIT, f"{head}: the fleet waits, {case.blocker} is moving; {then}"
        )
    if not case.can_resend:
        return StuckResponse(
            StuckAction.WAIT, f"{head}: the fleet waits (no goal here to send again); {then}"
        )
    return StuckResponse(
        StuckAction.REPLAN,
        f"{head}: the fleet sends its goal again so that it plans around it; {then}",
    )


def give_up(case: StuckCase, stuck_for: float) -> StuckResponse:
    """The robot is still stuck after the fleet's first response: abort, saying why."""
    return StuckResponse(
        StuckAction.ABORT,
        f"{case.robot} is still stuck after {stuck_for:.0f} s, {case.why}: the fleet aborts "
        "its goal and halts it",
    )
