"""The recorder of this process, made once with its configuration, plans and retention."""

from __future__ import annotations

from collections.abc import Callable
from typing import TypeVar

from django.conf import settings
from django.db import connection

from telemetry.domain.events import EventDraft
from telemetry.events import foreign_events

from .elsewhere import flush_elsewhere
from .plans import Plan, Retention, plans_for, retentions
from .recorder import Recorder, RecorderConfig, recording_on

T = TypeVar("T")

_recorder: Recorder | None = None


def start_recorder() -> Recorder | None:
    """This process's recorder, made and started on first call (the server's: from
    ``cloudnav_web.background``, with the first hub); None when recording is off.

    It is stopped at the process's end (``cloudnav_core.workers.REGISTRY``), finishing
    its files; a process killed outright leaves files
    that are read up to their last chunk and repaired by the next start."""
    global _recorder
    if _recorder is None:
        if not recording_on():
            return None
        _recorder = Recorder(
            RecorderConfig.load(), _plans, _retentions, foreign_events=_foreign_events
        )
        _recorder.start()  # a registered worker: stopped and joined at the end
    return _recorder


def flush_recordings(robots: list[str]) -> None:
    """Have the recorders of ``robots`` write out what they hold of them (before an export
    reads their files): this process's, and in scaled mode those of the processes the
    robots are connected to."""
    if _recorder is not None:
        _recorder.flush(robots)
    redis_url = getattr(settings, "REDIS_URL", "") or ""
    if redis_url and robots:
        flush_elsewhere(redis_url, robots)


def recording_config() -> RecorderConfig:
    """Where recordings are read from (the settings, as the recorder read them)."""
    return RecorderConfig.load()


def _closing(query: Callable[[], T]) -> T:
    """Run ``query`` on the recorder's thread and close its database connection after, so
    the thread never holds one between passes."""
    try:
        return query()
    finally:
        connection.close()


def _plans(robots: list[str]) -> dict[str, Plan]:
    return _closing(lambda: plans_for(robots))


def _retentions() -> list[Retention]:
    return _closing(retentions)


def _foreign_events(after: int | None, robots: frozenset[str]) -> tuple[int, list[EventDraft]]:
    return _closing(lambda: foreign_events(after, robots))
