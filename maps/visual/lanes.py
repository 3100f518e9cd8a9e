"""Relocalisation work within a bound, robots first: the threads that answer
``/cloudnav/relocalise`` and ``POST /api/relocalise`` alike.

A query costs tens of milliseconds of CPU per image (more while the machine is busy), so
the process answers at most ``workers`` at once, whichever path they came by, and never
on the event loop that relays topics. Waiting calls queue in two lanes: robots' (a robot
that cannot place itself cannot drive) and people's. A free thread takes a robot's call
first, and people's calls never occupy more than ``workers - 1`` threads (all of them when
there is one), so a robot's call waits at most for the calls already running, never for
the people queued. Each lane holds at most ``waiting`` calls and each caller at most
``per_caller`` calls, waiting or running; beyond either the call is refused at once
(``RelocalisationBusy``; the lanes drop the newest, and count it in ``refused``), so a
flood costs a bounded amount of memory and time. The threads are named workers
(``cloudnav_core.workers``), started with the server (``start_relocalisation``, from
``cloudnav_web.background``) and stopped and joined at the process's end; what a call
needs (keyframes, the vocabulary) loads with the call.
"""

from __future__ import annotations

import threading
from collections import Counter, deque
from collections.abc import Callable
from concurrent.futures import Future
from dataclasses import dataclass
from typing import Any

from django.conf import settings

from cloudnav_core.workers import Started, Worker

PER_CALLER = 2
"""Calls one caller may have waiting or running at once."""


class RelocalisationBusy(Exception):
    """The call is refused for now: ``own`` when the caller's own share is spent (429),
    else the server's lane is full (503)."""

    def __init__(self, message: str, own: bool) -> None:
        super().__init__(message)
        self.own = own


@dataclass(frozen=True)
class Caller:
    """Who asks: ``key`` names them (one share per key); ``robot`` picks the lane."""

    key: str
    robot: bool


@dataclass(frozen=True)
class _Call:
    caller: Caller
    work: Callable[[], Any]
    future: Future[Any]


class RelocalisationLanes:
    """``workers`` threads (once ``start``ed) taking calls from two lanes."""

    def __init__(self, workers: int, waiting: int, per_caller: int = PER_CALLER) -> None:
        self.workers = max(1, workers)
        self.waiting = waiting
        self.per_caller = per_caller
        self.people_share = max(1, self.workers - 1)
        self._robots: deque[_Call] = deque()
        self._people: deque[_Call] = deque()
        self._people_running = 0
        self._callers: Counter[str] = Counter()
        self.refused = 0  # calls refused: the caller's share or the lane was full
        self._ready = threading.Condition()
        self._workers = [
            Worker(f"relocalise-{n}", self._serve, wake=self._wake_all) for n in range(self.workers)
        ]

    def start(self) -> RelocalisationLanes:
        """Start the threads (they wait for calls); return the lanes."""
        for worker in self._workers:
            worker.start()
        return self

    def submit(self, caller: Caller, work: Callable[[], Any]) -> Future[Any]:
        """Queue ``work`` for ``caller``; its future holds what it returns or raises.
        Raises RelocalisationBusy when the caller's share or the lane is full."""
        lane = self._robots if caller.robot else self._people
        with self._ready:
            if self._callers[caller.key] >= self.per_caller:
                self.refused += 1
                raise RelocalisationBusy(
                    "your other relocalisation requests are still being answered; "
                    "ask again when they are done",
                    own=True,
                )
            if len(lane) >= self.waiting:
                self.refused += 1
                raise RelocalisationBusy(
                    "the server is answering other relocalisation requests; ask again shortly",
                    own=False,
                )
            call = _Call(caller, work, Future())
            lane.append(call)
            self._callers[caller.key] += 1
            self._ready.notify_all()
        return call.future

    def _wake_all(self) -> None:
        with self._ready:
            self._ready.notify_all()

    def _next(self, stopping: threading.Event) -> _Call | None:
        """The next call a free thread may take: a robot's, else a person's while people
        hold fewer than their share of the threads; None once the thread is stopping."""
        with self._ready:
            while not stopping.is_set():
                if self._robots:
                    return self._robots.popleft()
                if self._people and self._people_running < self.people_share:
                    self._people_running += 1
                    return self._people.popleft()
                self._ready.wait()
            return None

    def _serve(self, stopping: threading.Event) -> None:
        while (call := self._next(stopping)) is not None:
            try:
                if call.future.set_running_or_notify_cancel():
                    _run(call)
            finally:
                self._done(call.caller)

    def _done(self, caller: Caller) -> None:
        with self._ready:
            if not caller.robot:
                self._people_running -= 1
            self._callers[caller.key] -= 1
            if self._callers[caller.key] <= 0:
                del self._callers[caller.key]
            self._ready.notify_all()


def _run(call: _Call) -> None:
    try:
        result = call.work()
    except BaseException as error:  # the caller's to handle; the thread lives on
        call.future.set_exception(error)
    else:
        call.future.set_result(result)


_LANES: Started[RelocalisationLanes] = Started("relocalisation")


def start_relocalisation() -> RelocalisationLanes:
    """Make this process's lanes (``CLOUDNAV_RELOCALISE_WORKERS`` threads,
    ``CLOUDNAV_RELOCALISE_QUEUE`` calls waiting in each lane) and start their threads,
    once; return the lanes."""
    return _LANES.start(
        lambda: RelocalisationLanes(
            settings.CLOUDNAV_RELOCALISE_WORKERS, settings.CLOUDNAV_RELOCALISE_QUEUE
        ).start()
    )


def relocalisation_lanes() -> RelocalisationLanes:
    """This process's lanes. Raises NotStarted before ``start_relocalisation``."""
    return _LANES.get()
