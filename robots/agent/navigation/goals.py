"""``GoalBoard`` keeps goals as an actionlib action server does: a new goal preempts the
active one (PREEMPTED), a cancel preempts it too, and each ends SUCCEEDED or ABORTED;
``status_array`` turns it into ``nav_status``."""

from __future__ import annotations

from dataclasses import dataclass, field

from cloudnav_core.messages import GoalStatus, StatusEntry


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
