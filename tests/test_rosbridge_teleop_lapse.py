"""The teleop lock lapses when its holder stops driving: asking for it again keeps nothing,
and it lapses exactly ``CLOUDNAV_TELEOP_LOCK_TTL`` after the last command (held until just
before, free just after), measured on a monotonic clock."""

from __future__ import annotations

import asyncio
import time

import pytest

from tests.fixtures_live import robot_listening

pytestmark = pytest.mark.django_db(transaction=True)

GO = {"linear": {"x": 0.3, "y": 0.0, "z": 0.0}, "angular": {"x": 0.0, "y": 0.0, "z": 0.0}}
MARGIN = 0.5  # seconds either side of the TTL: a loaded machine answers late, never early


async def acquire(client, action="acquire", id="lock"):
    response = await client.call("/cloudnav/teleop_lock", {"robot": "r1", "action": action}, id)
    return response["values"]


async def test_an_idle_page_asking_again_does_not_keep_the_lock(
    rosbridge, token, operator, second_operator, settings
):
    settings.CLOUDNAV_TELEOP_LOCK_TTL = ttl = 1.0
    idle, other = await rosbridge(user=operator), await rosbridge(user=second_operator)
    assert (await acquire(idle))["success"] is True
    taken_by = time.monotonic() + ttl + MARGIN
    while True:
        await acquire(idle, id="renew")  # what an open, idle tab used to do every 2 s
        if (await acquire(other, id="other"))["success"]:
            break
        assert time.monotonic() < taken_by, "an idle holder kept the lock by asking again"
        await asyncio.sleep(0.1)


async def test_the_lock_lapses_at_the_ttl_after_the_last_command(
    rosbridge, token, operator, second_operator, settings
):
    settings.CLOUDNAV_TELEOP_LOCK_TTL = ttl = 3.0
    driver, other = await rosbridge(user=operator), await rosbridge(user=second_operator)
    assert (await acquire(driver))["success"] is True
    # Commands for longer than a third of the TTL, so the store is renewed while driving.
    stop_driving = time.monotonic() + 1.9
    while time.monotonic() < stop_driving:
        last_sent = time.monotonic()
        await driver.send(op="publish", topic="/r1/cmd_vel", msg=GO)
        await asyncio.sleep(0.1)
    await driver.sync()
    last_handled = time.monotonic()  # the server had the last command by now

    held_until = last_sent + ttl - MARGIN
    refused_near_the_bound = False
    while True:
        answer = await acquire(other, id="other")
        answered = time.monotonic()
        if answer["success"]:
            break
        refused_near_the_bound |= answered > last_sent + ttl / 2
        assert answered < last_handled + ttl + MARGIN, "the lock outlived its TTL"
        await asyncio.sleep(0.05)
    assert answered > held_until, f"lapsed {last_sent + ttl - answered:.2f} s early"
    assert refused_near_the_bound


async def test_a_building_admin_takes_the_lock_from_its_holder(rosbridge, token, operator, admin):
    robot = await robot_listening(rosbridge, token)
    holder, boss = await rosbridge(user=operator), await rosbridge(user=admin)
    assert (await acquire(holder))["success"] is True
    taken = await acquire(boss, "take")
    assert taken == {"success": True, "holder": "user:admin", "message": "taken from user:operator"}
    await holder.send(op="publish", topic="/r1/cmd_vel", msg=GO)
    await boss.send(op="publish", topic="/r1/cmd_vel", msg=GO)
    moving = await robot.receive_until(lambda f: f["msg"]["linear"]["x"] > 0)
    assert moving["msg"] == GO
    status = await acquire(holder, "status", id="status")
    assert status["holder"] == "user:admin"


async def test_an_operator_cannot_take_the_lock(rosbridge, token, operator, second_operator):
    holder, other = await rosbridge(user=operator), await rosbridge(user=second_operator)
    await acquire(holder)
    response = await other.call("/cloudnav/teleop_lock", {"robot": "r1", "action": "take"})
    assert response["result"] is False
    assert (await acquire(other, "status", id="status"))["holder"] == "user:operator"


async def ask(client, id="ask"):
    return await acquire(client, "ask", id)


async def test_asking_for_a_held_lock_tells_the_holder_and_passes_it_unless_refused(
    rosbridge, token, operator, second_operator, settings
):
    settings.CLOUDNAV_TELEOP_HANDOVER = 1.0
    holder, asker = await rosbridge(user=operator), await rosbridge(user=second_operator)
    await acquire(holder)
    asked = await ask(asker)
    assert asked["success"] is False
    assert asked["message"].startswith("user:operator is asked; control passes to you in")
    assert 0 < asked["handover_in"] <= 1.0
    told = await acquire(holder, "status", id="status")
    assert told["asked_by"] == "user:operator2"
    assert 0 < told["handover_in"] <= 1.0
    deadline = time.monotonic() + 5
    while not (await ask(asker, id="again"))["success"]:
        assert time.monotonic() < deadline, "the lock never passed to the asker"
        await asyncio.sleep(0.1)
    assert (await acquire(holder, "status", id="after"))["holder"] == "user:operator2"


async def test_the_holder_refuses_and_keeps_the_lock(
    rosbridge, token, operator, second_operator, settings
):
    settings.CLOUDNAV_TELEOP_HANDOVER = 1.0
    holder, asker = await rosbridge(user=operator), await rosbridge(user=second_operator)
    await acquire(holder)
    await ask(asker)
    refused = await acquire(holder, "refuse", id="refuse")
    assert refused == {
        "success": True,
        "holder": "user:operator",
        "message": "user:operator2 was refused",
    }
    await asyncio.sleep(1.2)  # past the handover
    again = await ask(asker, id="again")
    assert (again["success"], again["message"]) == (False, "user:operator keeps control")
    assert "asked_by" not in await acquire(holder, "status", id="status")
