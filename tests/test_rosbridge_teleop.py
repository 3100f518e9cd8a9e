"""Teleop: one lock holder drives a robot; silence or leaving stops the robot."""

from __future__ import annotations

import time

import pytest

from tests.conftest import make_building, make_user
from tests.fixtures_live import robot_listening
from tests.support.teleop import GO, ZERO

pytestmark = pytest.mark.django_db(transaction=True)


async def acquire(client, action="acquire"):
    response = await client.call("/cloudnav/teleop_lock", {"robot": "r1", "action": action})
    return response["values"]


async def test_cmd_vel_without_the_lock_is_dropped(rosbridge, token, operator):
    robot = await robot_listening(rosbridge, token)
    driver = await rosbridge(user=operator)
    await driver.send(op="publish", topic="/r1/cmd_vel", msg=GO)
    await driver.sync()
    assert await robot.quiet()


async def test_the_lock_holder_drives(rosbridge, token, operator):
    robot = await robot_listening(rosbridge, token)
    driver = await rosbridge(user=operator)
    assert (await acquire(driver))["success"] is True
    await driver.send(op="publish", topic="/r1/cmd_vel", msg=GO)
    assert (await robot.receive())["msg"] == GO


async def test_one_holder_at_a_time(rosbridge, token, operator, second_operator):
    robot = await robot_listening(rosbridge, token)
    first, second = await rosbridge(user=operator), await rosbridge(user=second_operator)
    assert (await acquire(first))["success"] is True
    refused = await acquire(second)
    assert refused["success"] is False
    assert refused["holder"] == "user:operator"
    await second.send(op="publish", topic="/r1/cmd_vel", msg=GO)
    await second.sync()
    assert await robot.quiet()


async def test_releasing_stops_the_robot_and_frees_the_lock(
    rosbridge, token, operator, second_operator
):
    robot = await robot_listening(rosbridge, token)
    first, second = await rosbridge(user=operator), await rosbridge(user=second_operator)
    await acquire(first)
    assert (await acquire(first, "release"))["success"] is True
    assert (await robot.receive())["msg"] == ZERO
    assert (await acquire(second))["success"] is True


async def test_silence_stops_the_robot_after_half_a_second(rosbridge, token, operator):
    robot = await robot_listening(rosbridge, token)
    driver = await rosbridge(user=operator)
    await acquire(driver)
    await driver.send(op="publish", topic="/r1/cmd_vel", msg=GO)
    assert (await robot.receive())["msg"] == GO
    started = time.monotonic()
    assert (await robot.receive(wait=2.0))["msg"] == ZERO
    assert 0.4 <= time.monotonic() - started < 3.0  # generous: a busy CI box stalls loops


async def test_commands_keep_the_robot_going(rosbridge, token, operator):
    robot = await robot_listening(rosbridge, token)
    driver = await rosbridge(user=operator)
    await acquire(driver)
    deadline = time.monotonic() + 1.0
    while time.monotonic() < deadline:
        await driver.send(op="publish", topic="/r1/cmd_vel", msg=GO)
        assert (await robot.receive())["msg"] == GO  # never a zero Twist in between


async def test_disconnecting_stops_the_robot_and_frees_the_lock(
    rosbridge, token, operator, second_operator
):
    robot = await robot_listening(rosbridge, token)
    first = await rosbridge(user=operator)
    await acquire(first)
    await first.close()
    assert (await robot.receive())["msg"] == ZERO
    second = await rosbridge(user=second_operator)
    assert (await acquire(second))["success"] is True


async def test_an_idle_lock_lapses(rosbridge, token, operator, second_operator, settings):
    settings.CLOUDNAV_TELEOP_LOCK_TTL = 0.2
    first, second = await rosbridge(user=operator), await rosbridge(user=second_operator)
    await acquire(first)
    deadline = time.monotonic() + 3
    while not (await acquire(second))["success"]:
        assert time.monotonic() < deadline, "the lock never lapsed"


async def test_a_robot_drives_itself_without_a_lock(rosbridge, token):
    robot = await robot_listening(rosbridge, token)
    await robot.send(op="publish", topic="cmd_vel", msg=GO)
    assert (await robot.receive())["msg"] == GO


async def test_anyone_who_sees_the_robot_is_told_who_holds_the_lock(
    rosbridge, token, operator, viewer
):
    driver, watcher = await rosbridge(user=operator), await rosbridge(user=viewer)
    assert (await acquire(watcher, "status"))["holder"] == ""
    await acquire(driver)
    assert (await acquire(watcher, "status")) == {
        "success": True,
        "holder": "user:operator",
        "message": "",
    }


@pytest.fixture
def stranger(db):
    """A viewer of another building."""
    user = make_user("viewer2", "viewer")
    make_building(code="other_1", members=[user])
    return user


async def test_a_viewer_of_another_building_is_not_told_who_holds_the_lock(
    rosbridge, token, stranger
):
    response = await (await rosbridge(user=stranger)).call(
        "/cloudnav/teleop_lock", {"robot": "r1", "action": "status"}
    )
    assert response["result"] is False


async def test_the_robots_own_token_cannot_drive_around_an_operators_lock(
    rosbridge, token, operator
):
    robot = await robot_listening(rosbridge, token)
    driver = await rosbridge(user=operator)
    assert (await acquire(driver))["success"] is True
    second_robot_connection = await rosbridge(token=token)
    await second_robot_connection.send(op="publish", topic="cmd_vel", msg=GO)
    await second_robot_connection.send(op="publish", topic="/r1/cmd_vel", msg=GO)
    await second_robot_connection.sync()
    assert await robot.quiet()


async def test_the_robots_own_token_drives_it_while_nobody_holds_the_lock(rosbridge, token):
    robot = await robot_listening(rosbridge, token)
    second_robot_connection = await rosbridge(token=token)
    await second_robot_connection.send(op="publish", topic="cmd_vel", msg=GO)
    assert (await robot.receive())["msg"] == GO


@pytest.mark.parametrize(
    "name", ["r1/cmd_vel", "/r1", "r1/../r2", "", " r1", 42, None, ["r1"], "r" * 65, "1r"]
)
async def test_the_lock_refuses_what_is_not_a_robots_name(rosbridge, token, operator, name):
    driver = await rosbridge(user=operator)
    response = await driver.call("/cloudnav/teleop_lock", {"robot": name, "action": "acquire"})
    assert response["result"] is False
    assert "'robot' must be a robot's name" in str(response["values"])
