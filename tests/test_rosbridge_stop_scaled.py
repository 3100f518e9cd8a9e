"""STOP across server processes: an operator on one process stops a robot connected to the
other; its goal is cancelled there (the relay's ``rb.stop``) and it gets a zero Twist."""

from __future__ import annotations

import pytest

from tests.support.teleop import ZERO

pytestmark = pytest.mark.scaled


async def test_an_operator_on_one_process_stops_a_robot_on_the_other(connect):
    robot, operator = await connect("r1", 0), await connect("operator", 1)
    await robot.send(op="advertise_service", service="cancel_goal", type="std_srvs/Trigger")
    await robot.send(op="subscribe", topic="cmd_vel")
    await robot.sync()
    answer = await operator.call("/cloudnav/stop", {"robot": "r1"}, id="stop")
    assert answer["result"] is True
    assert answer["values"]["goal"] == "cancel sent to the robot's server process"
    seen: dict[str, dict] = {}
    while not {"cancel", "zero"} <= set(seen):
        frame = await robot.receive()
        if frame.get("op") == "call_service" and frame["service"].endswith("cancel_goal"):
            seen["cancel"] = frame
        elif frame.get("op") == "publish" and frame["msg"] == ZERO:
            seen["zero"] = frame
