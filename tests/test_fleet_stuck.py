"""Nobody is stuck silently (issue 28, point 3): a robot with a goal that makes no
progress for ``CLOUDNAV_STUCK_AFTER`` seconds raises a ``robot_stuck`` alert naming what
blocks it (the robot standing in its way, else an unknown obstacle or person), cleared
when it moves again; through the real ASGI application, with two robots of the demo
building."""

from __future__ import annotations

import asyncio
import io
import json
import time
from collections.abc import Callable

import pytest
from channels.db import database_sync_to_async
from django.core.management import call_command

from maps.domain.reservations import Reservations
from telemetry.domain.events import EventDeriver, Kind
from telemetry.models import Event

ATRIUM = "boccioni_1/Atrium1"


def test_the_robot_standing_in_the_way_is_named_and_a_far_one_is_not():
    spots = Reservations(0.25)
    spots.stand("r1", "b/m", 0.0, 0.0)
    spots.stand("r2", "b/m", 0.6, 0.0)
    spots.stand("r3", "b/other", 0.1, 0.0)
    assert spots.blocking("r1") == ("r2", "r2 standing 0.6 m away")
    spots.stand("r2", "b/m", 3.0, 0.0)
    assert spots.blocking("r1") is None


def test_a_stuck_robot_with_nothing_known_in_its_way_blames_an_unknown_obstacle():
    deriver = EventDeriver(stuck_after=5.0, blocker=lambda _robot: None)
    deriver.connected("r1", 0.0)
    deriver.pose("r1", "b/A", 1.0, 1.0, 0.0)
    deriver.nav_status("r1", {"status_list": [{"goal_id": {"id": "g"}, "status": 1}]}, 0.0)
    deriver.pose("r1", "b/A", 1.01, 1.0, 5.9)  # heard, not silent; no progress
    [stuck] = deriver.tick(6.0)
    assert stuck.kind is Kind.STUCK
    assert stuck.message.endswith("blocked by an unknown obstacle or person")
    assert stuck.data["blocker"] == "unknown"


def pose(x: float, y: float) -> dict:
    return {"header": {"frame_id": ATRIUM}, "pose": {"position": {"x": x, "y": y, "z": 0.0}}}


ACTIVE = {"status_list": [{"goal_id": {"id": "g1"}, "status": 1, "text": "driving"}]}


def stuck_alert() -> Event | None:
    return Event.objects.filter(robot__name="robot_0", kind=Kind.STUCK.value).first()


async def eventually(check: Callable[[], bool], wait: float = 30.0) -> None:
    deadline = time.monotonic() + wait
    while not await database_sync_to_async(check)():
        assert time.monotonic() < deadline, "the condition never held"
        await asyncio.sleep(0.1)


async def saying(robot, *messages: tuple[str, dict], until: asyncio.Event) -> None:
    """Publish ``messages`` (topic, message) every 0.2 s until ``until`` is set."""
    while not until.is_set():
        for topic, msg in messages:
            await robot.send(op="publish", topic=topic, msg=msg)
        await asyncio.sleep(0.2)


@pytest.mark.django_db(transaction=True)
async def test_a_robot_blocked_by_a_standing_robot_raises_a_stuck_alert_naming_it(
    rosbridge, settings, tmp_path
):
    settings.CLOUDNAV_STUCK_AFTER = 2.0
    tokens = tmp_path / "tokens.json"
    await database_sync_to_async(call_command)(
        "seed_demo", "--robots", "2", "--tokens-file", str(tokens), stdout=io.StringIO()
    )
    token = json.loads(tokens.read_text())
    standing = await rosbridge(token=token["robot_1"])
    await standing.send(op="publish", topic="pose", msg=pose(20.0, 23.2))
    await standing.sync()
    blocked = await rosbridge(token=token["robot_0"])
    done = asyncio.Event()
    talk = asyncio.create_task(
        saying(blocked, ("pose", pose(20.0, 23.9)), ("nav_status", ACTIVE), until=done)
    )
    try:
        await eventually(lambda: stuck_alert() is not None)
        alert = await database_sync_to_async(stuck_alert)()
        assert alert is not None
        assert alert.alert
        assert alert.data["blocker"] == "robot_1"
        assert "blocked by robot_1 standing 0.7 m away" in alert.message
        assert alert.cleared_at is None
        done.set()
        await talk
        done.clear()
        talk = asyncio.create_task(
            saying(blocked, ("pose", pose(20.0, 24.6)), ("nav_status", ACTIVE), until=done)
        )
        await eventually(lambda: (a := stuck_alert()) is not None and a.cleared_at is not None)
    finally:
        done.set()
        await talk
