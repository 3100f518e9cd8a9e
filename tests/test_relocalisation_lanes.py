"""The relocalisation lanes (issue 23 point 13): a bounded number of calls at once from
REST and rosbridge alike, robots' calls first and never queued behind people's, and a
flood refused at once. Real threads; calls that hold until the test lets them go."""

from __future__ import annotations

import threading
from collections.abc import Callable, Iterator
from concurrent.futures import Future

import pytest

from maps.visual.lanes import Caller, RelocalisationBusy, RelocalisationLanes

DEADLINE = 30.0
ROBOT = Caller("robot:scout", robot=True)


def person(n: int) -> Caller:
    return Caller(f"user:operator{n}", robot=False)


class Calls:
    """Work that records when it starts and holds until released."""

    def __init__(self) -> None:
        self.started: list[str] = []
        self.lock = threading.Lock()
        self.release = threading.Event()
        self.progress = threading.Condition(self.lock)

    def work(self, name: str, hold: bool = True) -> Callable[[], str]:
        def run() -> str:
            with self.progress:
                self.started.append(name)
                self.progress.notify_all()
            if hold:
                assert self.release.wait(DEADLINE)
            return name

        return run

    def until_started(self, count: int) -> list[str]:
        with self.progress:
            assert self.progress.wait_for(lambda: len(self.started) >= count, DEADLINE)
            return list(self.started)


@pytest.fixture
def calls() -> Iterator[Calls]:
    held = Calls()
    yield held
    held.release.set()


def done(future: Future[str]) -> str:
    return future.result(timeout=DEADLINE)


def test_a_robots_call_runs_at_once_while_people_hold_their_share(calls: Calls) -> None:
    lanes = RelocalisationLanes(workers=2, waiting=8).start()
    people = [lanes.submit(person(n), calls.work(f"p{n}")) for n in range(3)]
    assert calls.until_started(1) == ["p0"]  # people take one of the two threads
    robot = lanes.submit(ROBOT, calls.work("robot", hold=False))
    assert done(robot) == "robot"
    assert calls.started == ["p0", "robot"]  # the two people waiting still wait
    calls.release.set()
    assert [done(f) for f in people] == ["p0", "p1", "p2"]


def test_a_robots_call_goes_before_the_people_waiting_when_there_is_one_thread(
    calls: Calls,
) -> None:
    lanes = RelocalisationLanes(workers=1, waiting=8).start()
    people = [lanes.submit(person(n), calls.work(f"p{n}")) for n in range(3)]
    calls.until_started(1)
    robot = lanes.submit(ROBOT, calls.work("robot"))
    calls.release.set()
    assert done(robot) == "robot"
    for future in people:
        done(future)
    assert calls.started == ["p0", "robot", "p1", "p2"]


def test_a_caller_with_two_calls_in_progress_is_told_to_wait(calls: Calls) -> None:
    lanes = RelocalisationLanes(workers=2, waiting=8).start()
    first = [lanes.submit(person(0), calls.work(f"p0.{n}")) for n in range(2)]
    with pytest.raises(RelocalisationBusy) as refused:
        lanes.submit(person(0), calls.work("p0.2"))
    assert refused.value.own
    other = lanes.submit(person(1), calls.work("p1"))  # another person's share is theirs
    calls.release.set()
    for future in [*first, other]:
        done(future)
    assert done(lanes.submit(person(0), calls.work("p0.3"))) == "p0.3"  # its share is back


def test_a_full_lane_is_refused_and_the_other_lane_is_not(calls: Calls) -> None:
    lanes = RelocalisationLanes(workers=2, waiting=2).start()
    running = lanes.submit(person(0), calls.work("p0"))
    calls.until_started(1)
    waiting = [lanes.submit(person(n), calls.work(f"p{n}")) for n in (1, 2)]
    with pytest.raises(RelocalisationBusy) as refused:
        lanes.submit(person(3), calls.work("p3"))
    assert not refused.value.own
    assert done(lanes.submit(ROBOT, calls.work("robot", hold=False))) == "robot"
    calls.release.set()
    assert [done(f) for f in [running, *waiting]] == ["p0", "p1", "p2"]


def test_a_call_that_fails_hands_its_error_to_the_caller_and_the_lanes_go_on() -> None:
    lanes = RelocalisationLanes(workers=1, waiting=2).start()

    def broken() -> str:
        raise ValueError("a bad image")

    with pytest.raises(ValueError, match="a bad image"):
        lanes.submit(ROBOT, broken).result(timeout=DEADLINE)
    assert lanes.submit(ROBOT, lambda: "next").result(timeout=DEADLINE) == "next"
