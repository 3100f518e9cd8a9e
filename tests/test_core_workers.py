"""The one way to run background work: bounded inboxes with a named, counted drop policy,
and named workers that stop within a deadline while busy."""

from __future__ import annotations

import asyncio
import threading
import time

import pytest

from cloudnav_core.workers import (
    Inbox,
    NotStarted,
    Policy,
    Pool,
    Registry,
    Started,
    TaskWorker,
    Worker,
)


def test_a_full_inbox_that_drops_the_oldest_keeps_the_newest_and_counts_the_rest() -> None:
    inbox: Inbox[int] = Inbox("scans", 3, Policy.DROP_OLDEST)
    for item in range(10):
        assert inbox.put(item)
    assert inbox.take_all() == [7, 8, 9]
    assert inbox.dropped == 7


def test_a_full_inbox_that_drops_the_newest_refuses_it_and_counts_it() -> None:
    inbox: Inbox[int] = Inbox("keyframes", 2, Policy.DROP_NEWEST)
    taken = [inbox.put(item) for item in range(5)]
    assert taken == [True, True, False, False, False]
    assert list(inbox) == [0, 1]
    assert inbox.dropped == 3


def test_a_full_blocking_inbox_makes_the_sender_wait_for_room() -> None:
    inbox: Inbox[int] = Inbox("calls", 1, Policy.BLOCK)
    inbox.put(1)
    threading.Timer(0.1, inbox.get).start()
    started = time.monotonic()
    assert inbox.put(2, timeout=2.0)
    assert time.monotonic() - started >= 0.05
    assert inbox.dropped == 0


def test_a_blocking_inbox_drops_and_counts_what_found_no_room_in_time() -> None:
    inbox: Inbox[int] = Inbox("calls", 1, Policy.BLOCK)
    inbox.put(1)
    assert not inbox.put(2, timeout=0.05)
    assert inbox.dropped == 1


def test_join_returns_once_every_item_put_is_done() -> None:
    inbox: Inbox[int] = Inbox("jobs", 4, Policy.DROP_NEWEST)
    inbox.put(1)
    assert not inbox.join(timeout=0.01)
    assert inbox.get() == 1
    inbox.done()
    assert inbox.join(timeout=0.01)


def _busy_worker(registry: Registry, inbox: Inbox[float]) -> Worker:
    def work(stopping: threading.Event) -> None:
        while not stopping.is_set() and (seconds := inbox.get()) is not None:
            time.sleep(seconds)  # the item in hand is finished, then the worker ends

    return Worker("busy", work, wake=inbox.close, registry=registry)


def test_a_busy_worker_stops_within_the_deadline_and_leaves_the_rest_waiting() -> None:
    registry = Registry()
    inbox: Inbox[float] = Inbox("work", 100, Policy.BLOCK)
    worker = _busy_worker(registry, inbox)
    for _ in range(50):
        inbox.put(0.1)
    worker.start()
    time.sleep(0.05)
    started = time.monotonic()
    assert registry.stop_and_join(deadline=2.0) == []
    assert time.monotonic() - started < 0.5
    assert not worker.alive
    assert len(inbox) > 40


def test_a_worker_past_the_deadline_is_named() -> None:
    registry = Registry()
    inbox: Inbox[float] = Inbox("work", 1, Policy.BLOCK)
    inbox.put(0.5)
    worker = _busy_worker(registry, inbox)
    worker.start()
    time.sleep(0.05)
    assert registry.stop_and_join(deadline=0.05) == ["busy"]
    assert worker.join(1.0)


def test_a_stopped_pool_ends_its_work_in_hand_and_cancels_the_rest() -> None:
    registry = Registry()
    pool = Pool("encoders", 1, registry=registry)
    running = pool.executor.submit(time.sleep, 0.2)
    waiting = pool.executor.submit(time.sleep, 0.2)
    time.sleep(0.05)
    assert registry.stop_and_join(deadline=2.0) == []
    assert running.done()
    assert not running.cancelled()
    assert waiting.cancelled()


def test_the_registry_cancels_its_task_workers_then_joins_its_threads() -> None:
    registry = Registry()
    inbox: Inbox[float] = Inbox("work", 10, Policy.BLOCK)
    worker = _busy_worker(registry, inbox)

    async def forever() -> None:
        await asyncio.sleep(3600)

    async def run() -> list[str]:
        task_worker = TaskWorker("runner", forever, registry=registry)
        task_worker.start()
        worker.start()
        inbox.put(0.1)
        assert sorted(registry.names()) == ["busy", "runner"]
        late = await registry.finish(deadline=2.0)
        assert task_worker.task is not None
        assert task_worker.task.cancelled()
        return late

    assert asyncio.run(run()) == []
    assert not worker.alive


def test_a_task_worker_that_ends_leaves_the_registry() -> None:
    registry = Registry()

    async def brief() -> None:
        await asyncio.sleep(0)

    async def run() -> None:
        TaskWorker("brief", brief, registry=registry).start()
        assert registry.names() == ["brief"]
        await asyncio.sleep(0.01)

    asyncio.run(run())
    assert registry.names() == []


def test_the_processs_one_worker_is_made_once_and_asked_for_in_vain_before() -> None:
    one: Started[object] = Started("the test's worker")
    with pytest.raises(NotStarted, match="the test's worker was not started"):
        one.get()
    made = one.start(object)
    assert one.start(object) is made
    assert one.get() is made
