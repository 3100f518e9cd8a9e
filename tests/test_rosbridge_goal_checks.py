"""A goal on an obstacle is refused when it is sent, not after the drive: in the demo
building, a goal on Atrium 1's pillar for a robot in Corridor A never reaches the robot,
and the pages' ``/cloudnav/check_pose`` says why; an initial pose inside a wall likewise."""

from __future__ import annotations

import io
import json

import pytest
from django.contrib.auth.models import User
from django.core.management import call_command

from tests.conftest import make_user
from tests.fixtures_live import robot_listening

pytestmark = pytest.mark.django_db(transaction=True)

PILLAR = (20.2, 21.4)  # the centre of one of Atrium 1's four pillars
ATRIUM_1 = (20.0, 23.2)  # between the door and the central pillar
CHECK_POSE = "/cloudnav/check_pose"


@pytest.fixture
def demo(tmp_path):
    """The demo building, its operator, and robot_0's token."""
    tokens = tmp_path / "tokens.json"
    call_command("seed_demo", "--robots", "1", "--tokens-file", str(tokens), stdout=io.StringIO())
    return User.objects.get(username="operator"), json.loads(tokens.read_text())["robot_0"]


def goal(map_id: str, x: float, y: float) -> dict:
    return {
        "header": {"frame_id": map_id},
        "pose": {"position": {"x": x, "y": y, "z": 0.0}, "orientation": {"w": 1.0}},
    }


def initial_pose(map_id: str, x: float, y: float) -> dict:
    stamped = goal(map_id, x, y)
    return {
        "header": stamped["header"],
        "pose": {"pose": stamped["pose"], "covariance": [0.0] * 36},
    }


async def test_a_goal_on_a_pillar_never_reaches_the_robot(rosbridge, demo):
    operator, token = demo
    robot = await robot_listening(rosbridge, token, "goal", "initialpose")
    page = await rosbridge(user=operator)
    await page.send(op="set_level", level="error")
    await page.send(op="publish", topic="/robot_0/goal", msg=goal("boccioni_1/Atrium1", *PILLAR))
    refusal = await page.receive_until(lambda f: f.get("op") == "status")
    assert "in an obstacle" in refusal["msg"]
    assert await robot.quiet()
    await page.send(op="publish", topic="/robot_0/goal", msg=goal("boccioni_1/Atrium1", *ATRIUM_1))
    sent = await robot.receive_until(lambda f: f.get("op") == "publish")
    assert sent["msg"]["pose"]["position"]["x"] == pytest.approx(ATRIUM_1[0])


async def test_the_page_is_told_why_before_it_sends(rosbridge, demo):
    operator, _ = demo
    page = await rosbridge(user=operator)
    pillar = {"map_id": "boccioni_1/Atrium1", "x": PILLAR[0], "y": PILLAR[1]}
    refused = await page.call(CHECK_POSE, pillar)
    assert refused["values"]["success"] is False
    assert refused["values"]["message"].startswith("The goal (20.20, 21.40) is in an obstacle")
    free = {"map_id": "boccioni_1/Atrium1", "x": ATRIUM_1[0], "y": ATRIUM_1[1]}
    assert (await page.call(CHECK_POSE, free, id="free"))["values"] == {
        "success": True,
        "message": "",
    }


@pytest.mark.parametrize(
    ("point", "why"),
    [((0.0, 0.0), "outside the map"), ((8.0, 21.9), "in an obstacle")],
)
async def test_an_initial_pose_inside_a_wall_or_outside_is_refused(rosbridge, demo, point, why):
    operator, token = demo
    robot = await robot_listening(rosbridge, token, "goal", "initialpose")
    page = await rosbridge(user=operator)
    await page.send(op="set_level", level="error")
    pose = initial_pose("boccioni_1/CorridorA", *point)
    await page.send(op="publish", topic="/robot_0/initialpose", msg=pose)
    refusal = await page.receive_until(lambda f: f.get("op") == "status")
    assert why in refusal["msg"]
    assert await robot.quiet()


async def test_a_goal_naming_no_sub_map_is_refused(rosbridge, demo):
    operator, token = demo
    robot = await robot_listening(rosbridge, token, "goal", "initialpose")
    page = await rosbridge(user=operator)
    await page.send(op="set_level", level="error")
    await page.send(op="publish", topic="/robot_0/goal", msg=goal("boccioni_1/Nowhere", 1, 1))
    refusal = await page.receive_until(lambda f: f.get("op") == "status")
    assert "names no sub-map" in refusal["msg"]
    assert await robot.quiet()


@pytest.fixture
def stranger(demo):
    """An operator of no building."""
    return make_user("outsider9", "operator")


async def test_check_pose_rejects_outsider(rosbridge, stranger):
    reply = await (await rosbridge(user=stranger)).call(
        CHECK_POSE, {"map_id": "boccioni_1/Atrium1", "x": 1.0, "y": 1.0}
    )
    assert reply["result"] is False
