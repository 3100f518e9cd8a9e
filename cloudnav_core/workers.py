"""Background work, one way: bounded inboxes and named workers that stop on shutdown.

An ``Inbox`` holds at most ``size`` items; what it does when full is named when it is
made (``Policy``) and what it dropped is counted, so no queue forgets silently. A worker
is a named thread (``Worker``), a named thread pool (``Pool``) or a named asyncio task
(``TaskWorker``); each registers with ``REGISTRY`` when it starts, and the process's end
(``REGISTRY.finish`` under daphne, ``REGISTRY.stop_and_join`` at exit otherwise) stops
them all and joins them within a deadline, so none is cut off half way through a write.
What a process has one of (a queue and its worker, a pool) it holds in a ``Started``,
started once by the server's composition root and asked for after (``NotStarted``
before).
"""

from __future__ import annotations

import asyncio
import atexit
import logging
import threading
import time
from collections import deque
from collections.abc import Callable, Coroutine, Iterator
from concurrent.futures import ThreadPoolExecutor
from enum import Enum
from typing import Any, Generic, Protocol, TypeVar

logger = logging.getLogger(__name__)

T = TypeVar("T")

DEADLINE = 5.0
"""Seconds the registry waits for its workers at the end, all together."""


class Policy(Enum):
    """What a full inbox does with one more item."""

    DROP_OLDEST = "drop the oldest"  # the newest matters most (scans, frames)
    DROP_NEWEST = "drop the newest"  # the sender is told and may try again later
    BLOCK = "block"  # the sender waits for room (or its timeout, then it is dropped)


class Inbox(Generic[T]):
    """At most ``size`` items waiting, safe across threads; ``dropped`` counts the items
    ``policy`` dropped."""

    def __init__(self, name: str, size: int, policy: Policy) -> None:
        self.name = name
        self.size = size
        self.policy = policy
        self.dropped = 0
        self._items: deque[T] = deque()
        self._unfinished = 0  # put and not yet done (``done``, ``take_all``) or dropped
        self._closed = False
        self._lock = threading.Lock()
        self._changed = threading.Condition(self._lock)
        self._waiting = 0  # threads waiting on ``_changed``: only they need waking

    def _wait(self, until: Callable[[], object], timeout: float | None) -> bool:
        self._waiting += 1
        try:
            return bool(self._changed.wait_for(until, timeout))
        finally:
            self._waiting -= 1

    def _wake(self) -> None:
        # A tap on the relay's hot path puts into an inbox nobody waits on (its worker
        # polls): notifying nobody would cost more than the append itself.
        if self._waiting:
            self._changed.notify_all()

    def put(self, item: T, timeout: float | None = None) -> bool:
        """Add ``item``; False when it is the one dropped (``DROP_NEWEST``, or ``BLOCK``
        past ``timeout``)."""
        with self._lock:
            if len(self._items) >= self.size:
                if self.policy is Policy.DROP_NEWEST or (
                    self.policy is Policy.BLOCK and not self._room(timeout)
                ):
                    self.dropped += 1
                    return False
                if self.policy is Policy.DROP_OLDEST:
                    self._items.popleft()
                    self._unfinished -= 1
                    self.dropped += 1
            self._items.append(item)
            self._unfinished += 1
            self._wake()
        return True

    def _room(self, timeout: float | None) -> bool:
        return self._wait(lambda: len(self._items) < self.size, timeout)

    def get(self, timeout: float | None = None) -> T | None:
        """The oldest item, waiting for one at most ``timeout`` seconds; None when none
        came in time or the inbox is closed."""
        with self._lock:
            if not self._wait(lambda: self._items or self._closed, timeout) or self._closed:
                return None
            item = self._items.popleft()
            self._wake()
            return item

    def take_all(self) -> list[T]:
        """Every item waiting, oldest first, taken at once (and counted as done)."""
        with self._lock:
            items = list(self._items)
            self._items.clear()
            self._unfinished -= len(items)
            self._wake()
        return items

    def done(self) -> None:
        """One item taken by ``get`` is handled."""
        with self._lock:
            self._unfinished -= 1
            self._wake()

    def join(self, timeout: float | None = None) -> bool:
        """Wait until every item put is handled or dropped; False past ``timeout``."""
        with self._lock:
            return self._wait(lambda: self._unfinished <= 0, timeout)

    def close(self) -> None:
        """Wake every ``get`` with None, now and from now on (the worker is stopping)."""
        with self._lock:
            self._closed = True
            self._wake()

    def __len__(self) -> int:
        return len(self._items)

    def __iter__(self) -> Iterator[T]:
        return iter(list(self._items))

    def __getitem__(self, index: int) -> T:
        return self._items[index]


class Stoppable(Protocol):
    """What the registry needs of a worker."""

    name: str

    def stop(self) -> None:
        """Ask the worker to end (it may finish the item in hand and write what it owes)."""
        ...

    def join(self, timeout: float) -> bool:
        """Wait for it to end, at most ``timeout`` seconds; False if it did not."""
        ...


class Registry:
    """Every worker of this process, to be stopped and joined at its end."""

    def __init__(self) -> None:
        self._workers: list[Stoppable] = []
        self._tasks: list[TaskWorker] = []
        self._lock = threading.Lock()

    def add(self, worker: Stoppable) -> None:
        with self._lock:
            if worker not in self._workers:
                self._workers.append(worker)

    def add_task(self, worker: TaskWorker) -> None:
        with self._lock:
            if worker not in self._tasks:
                self._tasks.append(worker)

    def discard_task(self, worker: TaskWorker) -> None:
        with self._lock:
            if worker in self._tasks:
                self._tasks.remove(worker)

    def names(self) -> list[str]:
        with self._lock:
            return [w.name for w in self._tasks] + [w.name for w in self._workers]

    def stop_and_join(self, deadline: float = DEADLINE) -> list[str]:
        """Stop every thread worker, then join each within what is left of ``deadline``
        seconds; the names of those still running."""
        with self._lock:
            workers, self._workers = self._workers, []
        for worker in workers:
            worker.stop()
        ends = time.monotonic() + deadline
        late = [w.name for w in workers if not w.join(max(0.0, ends - time.monotonic()))]
        if late:
            logger.warning("shutdown: workers still running: %s", ", ".join(late))
        return late

    async def finish(self, deadline: float = DEADLINE) -> list[str]:
        """Stop and await the task workers of the running loop, then stop and join the
        thread workers, all within ``deadline`` seconds; the names of those still running."""
        loop = asyncio.get_running_loop()
        ends = loop.time() + deadline
        logger.info("shutdown: stopping %s", ", ".join(self.names()) or "no workers")
        with self._lock:
            mine = [w for w in self._tasks if w.loop is loop]
            self._tasks = [w for w in self._tasks if w.loop is not loop]
        late = [w.name for w in mine if not await w.stop_and_wait(ends - loop.time())]
        return late + await asyncio.to_thread(self.stop_and_join, max(0.0, ends - loop.time()))


REGISTRY = Registry()
atexit.register(REGISTRY.stop_and_join)  # outside daphne (commands, tests): at exit


class NotStarted(RuntimeError):
    """A process's worker was asked for before it was started (the server starts every
    one from ``cloudnav_web.background``)."""


class Started(Generic[T]):
    """The process's one ``T`` (a worker, or what holds its workers), made and started once
    by ``start`` and handed to whoever asks after (``get``)."""

    def __init__(self, what: str) -> None:
        self.what = what
        self._value: T | None = None
        self._lock = threading.Lock()

    def start(self, make: Callable[[], T]) -> T:
        """Make and start it with ``make`` unless that was done; return it."""
        with self._lock:
            if self._value is None:
                self._value = make()
            return self._value

    def get(self) -> T:
        """Return it. Raises NotStarted before ``start``."""
        if self._value is None:
            raise NotStarted(f"{self.what} was not started (cloudnav_web.background starts it)")
        return self._value


class Worker:
    """A named thread running ``work(stopping)`` until ``stopping`` is set (``stop``);
    ``wake`` is called on ``stop`` to rouse a thread waiting for work (``Inbox.close``)."""

    def __init__(
        self,
        name: str,
        work: Callable[[threading.Event], None],
        wake: Callable[[], None] | None = None,
        registry: Registry = REGISTRY,
    ) -> None:
        self.name = name
        self.work = work
        self.wake = wake
        self.registry = registry
        self.stopping = threading.Event()
        self._thread: threading.Thread | None = None
        self._start_lock = threading.Lock()

    @property
    def alive(self) -> bool:
        return self._thread is not None and self._thread.is_alive()

    def start(self) -> None:
        """Start the thread unless it runs (or was stopped); registers the worker."""
        with self._start_lock:
            if self.alive or self.stopping.is_set():
                return
            self.registry.add(self)
            self._thread = threading.Thread(
                target=self.work, args=(self.stopping,), name=self.name, daemon=True
            )
            self._thread.start()

    def stop(self) -> None:
        self.stopping.set()
        if self.wake is not None:
            self.wake()

    def join(self, timeout: float) -> bool:
        if self._thread is not None:
            self._thread.join(timeout)
        return not self.alive


class Pool:
    """``threads`` named threads for ``loop.run_in_executor(pool.executor, ...)``; stopping
    cancels the work not begun and lets the work in hand end."""

    def __init__(self, name: str, threads: int, registry: Registry = REGISTRY) -> None:
        self.name = name
        self.executor = ThreadPoolExecutor(threads, thread_name_prefix=name)
        registry.add(self)

    def stop(self) -> None:
        self.executor.shutdown(wait=False, cancel_futures=True)

    def join(self, timeout: float) -> bool:
        # ThreadPoolExecutor waits without a timeout: wait in a thread of our own.
        waiting = threading.Thread(target=self.executor.shutdown, name=f"{self.name}-join")
        waiting.start()
        waiting.join(timeout)
        return not waiting.is_alive()


class TaskWorker:
    """A named asyncio task running ``work()`` on the loop that starts it; registers with
    the registry (until it ends), which cancels and awaits it at the end."""

    def __init__(
        self,
        name: str,
        work: Callable[[], Coroutine[Any, Any, None]],
        registry: Registry = REGISTRY,
    ) -> None:
        self.name = name
        self.work = work
        self.registry = registry
        self.task: asyncio.Task[None] | None = None
        self.loop: asyncio.AbstractEventLoop | None = None

    def start(self) -> None:
        self.loop = asyncio.get_running_loop()
        self.task = self.loop.create_task(self.work(), name=self.name)
        self.registry.add_task(self)
        self.task.add_done_callback(lambda _task: self.registry.discard_task(self))

    async def stop_and_wait(self, within: float) -> bool:
        """Cancel the task and wait for it, at most ``within`` seconds; False if it is
        still running."""
        if self.task is None:
            return True
        self.task.cancel()
        await asyncio.wait([self.task], timeout=max(0.0, within))
        return self.task.done()
