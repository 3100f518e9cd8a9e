"""Right of way and the stuck rule through the real ASGI application (issue 28, points 2
and 3): two robots of the demo building say where they are and what route they plan;
the server tells the one that must give way, on its ``right_of_way`` topic, where to
wait, and tells it to go once the other is through; a stuck robot is answered by the
fleet rule (wait, replan, abort), each choice an event that says which and why."""

from __future__ import annotations

import asyncio
import io
import json
import math
import time
from collections.abc import Callable
from typing import Any

import pytest
from channels.db import database_sync_to_async
from django.contrib.auth.models import User
from django.core.management import call_command

from cloudnav_core.messages import path_message, wait_order_of
from telemetry.domain.events import Kind
from telemetry.models import Event

live = pytest.mark.django_db(transaction=True)
CORRIDOR = "boccioni_1/CorridorA"
ATRIUM = "boccioni_1/Atrium1"


@pytest.fixture
def demo(tmp_path):
    tokens = tmp_path / "tokens.json"
    call_command("seed_demo", "--robots", "2", "--tokens-file", str(tokens), stdout=io.StringIO())
    return User.objects.get(username="operator"), json.loads(tokens.read_text())


def pose(x: float, y: float, map_id: str = CORRIDOR) -> dict[str, Any]:
    return {
        "header": {"frame_id": map_id},
        "pose": {"position": {"x": x, "y": y, "z": 0.0}, "orientation": {"w": 1.0}},
    }


def line(a: tuple[float, float], b: tuple[float, float]) -> list[tuple[float, float]]:
    n = int(math.dist(a, b) / 0.05)
    return [(a[0] + (b[0] - a[0]) * k / n, a[1] + (b[1] - a[1]) * k / n) for k in range(n + 1)]


async def robot_on_route(rosbridge, token: str, at: tuple[float, float], to: tuple[float, float]):
    """A robot listening to its right of way, standing at ``at`` with a plan to ``to``."""
    robot = await rosbridge(token=token)
    await robot.send(op="subscribe", topic="right_of_way")
    await robot.send(op="publish", topic="pose", msg=pose(*at))
    await robot.sync()  # before the plan: what the plan brings is read by the test
    await robot.send(op="publish", topic="plan", msg=path_message(CORRIDOR, line(at, to), 0.0))
    return robot


async def told(robot) -> dict[str, Any]:
    frame = await robot.receive_until(
        lambda f: f.get("op") == "publish" and f.get("topic") == "right_of_way"
    )
    return json.loads(frame["msg"]["data"])


def events_of(kind: Kind, robot: str) -> list[Event]:
    return list(Event.objects.filter(kind=kind.value, robot__name=robot).order_by("pk"))


async def eventually(check: Callable[[], bool], wait: float = 30.0) -> None:
    deadline = time.monotonic() + wait
    while not await database_sync_to_async(check)():
        assert time.monotonic() < deadline, "the condition never held"
        await asyncio.sleep(0.1)


@live
async def test_two_robots_meeting_in_a_door_one_waits_clear_of_the_other_until_it_is_through(
    rosbridge, demo
):
    _, tokens = demo
    first = await robot_on_route(rosbridge, tokens["robot_0"], (2.6, 23.8), (7.0, 23.8))
    second = await robot_on_route(rosbridge, tokens["robot_1"], (5.5, 23.8), (2.4, 23.8))
    wait = await told(second)
    assert wait["state"] == "wait"
    assert wait["waiting_for"] == "robot_0"
    assert wait["map_id"] == CORRIDOR
    order = wait_order_of({"data": json.dumps(wait)})
    assert order is not None
    spot = order.spot[:2]
    assert spot[0] > 3.8  # on its own side of the door
    assert min(math.dist(spot, p) for p in line((2.6, 23.8), (7.0, 23.8))) >= 0.8
    assert "robot_1 waits at" in wait["message"]
    assert await first.quiet()  # the one going first is told nothing
    await first.send(op="publish", topic="pose", msg=pose(4.9, 23.8))
    go = await told(second)
    assert go["state"] == "go"
    await eventually(lambda: len(events_of(Kind.RIGHT_OF_WAY, "robot_1")) == 2)
    waited, went = await database_sync_to_async(events_of)(Kind.RIGHT_OF_WAY, "robot_1")
    assert waited.data["state"] == "wait"
    assert waited.data["waiting_for"] == "robot_0"
    assert "for robot_0 to pass the narrow place" in waited.message
    assert went.data["state"] == "go"


@live
async def test_two_robots_crossing_at_one_tag_read_it_one_at_a_time(rosbridge, demo):
    # Both plan to where a robot reads tag 1 (Corridor A's east end, to Atrium 1): the
    # corridor is wide there, but the crossing is the server's narrow place all the same.
    _, tokens = demo
    reading = (17.3, 22.6)  # tag 1 at (17.8, 22.6), facing west: 0.5 m in front of it
    first = await robot_on_route(rosbridge, tokens["robot_0"], (15.5, 23.0), reading)
    second = await robot_on_route(rosbridge, tokens["robot_1"], (14.8, 22.0), reading)
    wait = await told(second)
    assert (wait["state"], wait["waiting_for"]) == ("wait", "robot_0")
    order = wait_order_of({"data": json.dumps(wait)})
    assert order is not None
    assert math.dist(order.spot[:2], reading) >= 1.5
    assert await first.quiet()
    await first.send(op="publish", topic="pose", msg=pose(18.4, 22.6, ATRIUM))  # tag read
    go = await told(second)
    assert go["state"] == "go"


@live
async def test_with_right_of_way_off_nobody_is_told_to_wait(rosbridge, demo, settings):
    settings.CLOUDNAV_RIGHT_OF_WAY = False
    _, tokens = demo
    await robot_on_route(rosbridge, tokens["robot_0"], (2.6, 23.8), (7.0, 23.8))
    second = await robot_on_route(rosbridge, tokens["robot_1"], (5.5, 23.8), (2.4, 23.8))
    assert await second.quiet()


@live
@pytest.mark.parametrize("topic", ["right_of_way", "mapping"])
async def test_a_robot_may_not_publish_what_only_the_server_tells_it(rosbridge, demo, topic):
    _, tokens = demo
    robot = await rosbridge(token=tokens["robot_0"])
    await robot.send(op="set_level", level="warning")
    await robot.send(op="publish", topic=topic, msg={"data": '{"state": "go"}'})
    refused = await robot.receive_until(lambda f: f.get("op") == "status")
    assert refused["level"] == "error"


# ---------------------------------------------------------------- stuck


ACTIVE = {"status_list": [{"goal_id": {"id": "g1"}, "status": 1, "text": "driving"}]}


async def saying(robot, *messages: tuple[str, Callable[[], dict]], until: asyncio.Event) -> None:
    """Publish ``messages`` (topic, message maker) every 0.2 s until ``until`` is set."""
    while not until.is_set():
        for topic, make in messages:
            await robot.send(op="publish", topic=topic, msg=make())
        await asyncio.sleep(0.2)


async def serve_cancel(robot) -> None:
    await robot.send(op="advertise_service", service="cancel_goal", type="std_srvs/Trigger")
    await robot.sync()


async def answer_cancels(robot, cancelled: asyncio.Event) -> None:
    while True:
        frame = await robot.receive_until(lambda f: f.get("op") in {"call_service", "publish"})
        if frame["op"] == "call_service":
            values = {"success": True, "message": "cancelled"}
            await robot.send(
                op="service_response", id=frame.get("id"), service=frame["service"],
                values=values, result=True,
            )  # fmt: skip
            cancelled.set()
            return


async def sent_behind_a_standing_robot(rosbridge, demo):
    """robot_0, serving cancels, given a goal past robot_1 standing 0.7 m in its way."""
    operator, tokens = demo
    standing = await rosbridge(token=tokens["robot_1"])
    await standing.send(op="publish", topic="pose", msg=pose(20.0, 23.2, ATRIUM))
    blocked = await rosbridge(token=tokens["robot_0"])
    await blocked.send(op="subscribe", topic="goal")
    await serve_cancel(blocked)
    page = await rosbridge(user=operator)
    await page.send(op="publish", topic="/robot_0/goal", msg=pose(20.0, 21.0, ATRIUM))
    await blocked.receive_until(lambda f: f.get("op") == "publish")
    return blocked


@live
async def test_a_robot_stuck_behind_a_standing_robot_is_replanned_then_aborted(
    rosbridge, demo, settings
):
    settings.CLOUDNAV_STUCK_AFTER = 2.0
    settings.CLOUDNAV_STUCK_GIVE_UP_AFTER = 3.0
    blocked = await sent_behind_a_standing_robot(rosbridge, demo)
    done = asyncio.Event()
    talk = asyncio.create_task(
        saying(
            blocked,
            ("pose", lambda: pose(20.0, 23.9, ATRIUM)),
            ("nav_status", lambda: ACTIVE),
            until=done,
        )
    )
    try:
        again = await blocked.receive_until(lambda f: f.get("op") == "publish", wait=60)
        assert again["msg"]["pose"]["position"]["y"] == pytest.approx(21.0)
        await eventually(lambda: len(events_of(Kind.FLEET_RULE, "robot_0")) >= 1)
        [replan] = await database_sync_to_async(events_of)(Kind.FLEET_RULE, "robot_0")
        assert replan.data["action"] == "replan"
        assert "robot_1 standing 0.7 m away" in replan.message
        assert "sends its goal again" in replan.message
        cancelled = asyncio.Event()
        await asyncio.wait_for(answer_cancels(blocked, cancelled), 60)
        await eventually(lambda: len(events_of(Kind.FLEET_RULE, "robot_0")) >= 2)
        abort = (await database_sync_to_async(events_of)(Kind.FLEET_RULE, "robot_0"))[1]
        assert abort.data["action"] == "abort"
        assert abort.severity == "error"
        assert "still stuck" in abort.message
        assert "aborts its goal" in abort.message
    finally:
        done.set()
        await talk


class RobotClock:
    """A robot's clock for its stamped statuses: it runs at the server's pace from 100 s
    until ``freeze`` and again after ``run``, as a simulation that stalls does."""

    def __init__(self) -> None:
        self.base, self.since = 100.0, time.monotonic()
        self.running = True

    def now(self) -> float:
        return self.base + (time.monotonic() - self.since if self.running else 0.0)

    def freeze(self) -> None:
        self.base, self.running = self.now(), False

    def run(self) -> None:
        self.since, self.running = time.monotonic(), True

    def status(self) -> dict:
        sec, fraction = divmod(self.now(), 1.0)
        stamp = {"sec": int(sec), "nanosec": int(fraction * 1e9)}
        return {"header": {"stamp": stamp}, **ACTIVE}


@live
async def test_the_stuck_rule_gives_up_after_the_robot_s_own_seconds(rosbridge, demo, settings):
    settings.CLOUDNAV_STUCK_AFTER = 2.0
    settings.CLOUDNAV_STUCK_GIVE_UP_AFTER = 3.0
    blocked = await sent_behind_a_standing_robot(rosbridge, demo)
    clock, done = RobotClock(), asyncio.Event()
    talk = asyncio.create_task(
        saying(
            blocked,
            ("pose", lambda: pose(20.0, 23.9, ATRIUM)),
            ("nav_status", clock.status),
            until=done,
        )
    )
    try:
        await blocked.receive_until(lambda f: f.get("op") == "publish", wait=60)  # replanned
        clock.freeze()  # its simulation stalls: no second of its own passes
        # Twice the give-up time of the server's clock: no cancel comes, nothing aborts.
        assert await blocked.nothing_more(2 * settings.CLOUDNAV_STUCK_GIVE_UP_AFTER)
        assert [e.data["action"] for e in await database_sync_to_async(events_of)(
            Kind.FLEET_RULE, "robot_0"
        )] == ["replan"]  # fmt: skip
        clock.run()  # its seconds pass again: it gives up 3 of them later
        call = await blocked.receive_until(lambda f: f.get("op") == "call_service", wait=30)
        await blocked.send(
            op="service_response", id=call.get("id"), service=call["service"],
            values={"success": True, "message": "cancelled"}, result=True,
        )  # fmt: skip
        await eventually(lambda: len(events_of(Kind.FLEET_RULE, "robot_0")) >= 2)
        abort = (await database_sync_to_async(events_of)(Kind.FLEET_RULE, "robot_0"))[1]
        assert abort.data["action"] == "abort"
    finally:
        done.set()
        await talk


@live
async def test_a_robot_stuck_behind_a_robot_that_is_moving_waits(rosbridge, demo, settings):
    settings.CLOUDNAV_STUCK_AFTER = 2.0
    settings.CLOUDNAV_STUCK_GIVE_UP_AFTER = 120.0
    _, tokens = demo
    mover = await rosbridge(token=tokens["robot_1"])
    blocked = await rosbridge(token=tokens["robot_0"])
    done = asyncio.Event()
    started = time.monotonic()

    def pacing() -> dict:  # to and fro 0.3 m every second, within 1.2 m of robot_0
        return pose(20.0, 23.0 + (0.3 if int(time.monotonic() - started) % 2 else 0.0), ATRIUM)

    talks = [
        asyncio.create_task(saying(mover, ("pose", pacing), until=done)),
        asyncio.create_task(
            saying(
                blocked,
                ("pose", lambda: pose(20.0, 23.9, ATRIUM)),
                ("nav_status", lambda: ACTIVE),
                until=done,
            )
        ),
    ]
    try:
        await eventually(lambda: len(events_of(Kind.FLEET_RULE, "robot_0")) >= 1)
        [rule] = await database_sync_to_async(events_of)(Kind.FLEET_RULE, "robot_0")
        assert rule.data["action"] == "wait"
        assert "robot_1 is moving" in rule.message
    finally:
        done.set()
        await asyncio.gather(*talks)
