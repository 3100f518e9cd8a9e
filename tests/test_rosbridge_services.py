"""Services and actions between clients, routed by id as rosbridge_suite routes them."""

from __future__ import annotations

import pytest

pytestmark = pytest.mark.django_db(transaction=True)


async def test_a_call_reaches_the_advertiser_and_the_answer_comes_back(rosbridge, token, operator):
    robot, caller = await rosbridge(token=token), await rosbridge(user=operator)
    await robot.send(op="advertise_service", service="dock", type="std_srvs/SetBool")
    await robot.sync()
    await caller.send(op="call_service", id="mine", service="/r1/dock", args={"data": True})
    request = await robot.receive()
    assert request == {  # under the name as the robot advertised it, as rosbridge does
        "op": "call_service",
        "id": "service_request:dock:1",
        "service": "dock",
        "args": {"data": True},
    }
    await robot.send(
        op="service_response",
        service="/r1/dock",
        id=request["id"],
        values={"success": True, "message": "docked"},
        result=True,
    )
    assert await caller.receive() == {
        "op": "service_response",
        "id": "mine",
        "service": "/r1/dock",
        "values": {"success": True, "message": "docked"},
        "result": True,
    }


async def test_concurrent_calls_are_answered_by_id(rosbridge, token, operator):
    robot, caller = await rosbridge(token=token), await rosbridge(user=operator)
    await robot.send(op="advertise_service", service="dock", type="std_srvs/SetBool")
    await robot.sync()
    await caller.send(op="call_service", id="a", service="/r1/dock", args={"data": True})
    await caller.send(op="call_service", id="b", service="/r1/dock", args={"data": False})
    first, second = await robot.receive(), await robot.receive()
    assert [first["id"], second["id"]] == ["service_request:dock:1", "service_request:dock:2"]
    for request, message in ((second, "two"), (first, "one")):
        await robot.send(
            op="service_response",
            service="/r1/dock",
            id=request["id"],
            values={"message": message},
            result=True,
        )
    answers = {(await caller.receive())["id"]: None for _ in range(2)}
    assert set(answers) == {"a", "b"}


async def test_the_provider_leaving_fails_the_waiting_calls(rosbridge, token, operator):
    robot, caller = await rosbridge(token=token), await rosbridge(user=operator)
    await robot.send(op="advertise_service", service="dock", type="std_srvs/SetBool")
    await robot.sync()
    await caller.send(op="call_service", id="a", service="/r1/dock", args={})
    await robot.receive()
    await robot.close()
    response = await caller.receive()
    assert response["result"] is False
    assert "unadvertised" in response["values"]


async def test_advertising_again_restarts_the_request_ids(rosbridge, token, operator):
    caller = await rosbridge(user=operator)
    for _ in range(2):
        robot = await rosbridge(token=token)
        await robot.send(op="advertise_service", service="dock", type="std_srvs/SetBool")
        await robot.sync()
        await caller.send(op="call_service", id="x", service="/r1/dock", args={})
        assert (await robot.receive())["id"] == "service_request:dock:1"
        await robot.close()
        await caller.receive()


async def test_an_unadvertised_service_is_gone(rosbridge, token, operator):
    robot, caller = await rosbridge(token=token), await rosbridge(user=operator)
    await robot.send(op="advertise_service", service="dock", type="std_srvs/SetBool")
    await robot.send(op="unadvertise_service", service="dock")
    await robot.sync()
    response = await caller.call("/r1/dock")
    assert response["result"] is False


async def test_a_stranger_cannot_answer_someone_elses_request(rosbridge, token, operator, admin):
    robot, caller = await rosbridge(token=token), await rosbridge(user=operator)
    intruder = await rosbridge(user=admin)
    await robot.send(op="advertise_service", service="dock", type="std_srvs/SetBool")
    await robot.sync()
    await caller.send(op="call_service", id="a", service="/r1/dock", args={})
    request = await robot.receive()
    await intruder.send(
        op="service_response", service="/r1/dock", id=request["id"], values={}, result=True
    )
    await intruder.sync()
    assert await caller.quiet()


async def test_an_action_goal_gets_feedback_and_a_result(rosbridge, token, operator):
    robot, caller = await rosbridge(token=token), await rosbridge(user=operator)
    await robot.send(op="advertise_action", action="navigate", type="nav2_msgs/NavigateToPose")
    await robot.sync()
    await caller.send(
        op="send_action_goal",
        id="goal-1",
        action="/r1/navigate",
        action_type="nav2_msgs/NavigateToPose",
        args={"pose": {}},
        feedback=True,
    )
    goal = await robot.receive()
    assert goal["op"] == "send_action_goal"
    assert goal["id"] == "action_goal:navigate:1"
    assert goal["action"] == "navigate"
    assert goal["args"] == {"pose": {}}
    await robot.send(
        op="action_feedback", action="/r1/navigate", id=goal["id"], values={"left": 3.0}
    )
    assert await caller.receive() == {
        "op": "action_feedback",
        "action": "/r1/navigate",
        "id": "goal-1",
        "values": {"left": 3.0},
    }
    await robot.send(
        op="action_result",
        action="/r1/navigate",
        id=goal["id"],
        values={"result": {}},
        status=4,
        result=True,
    )
    result = await caller.receive()
    assert result["op"] == "action_result"
    assert result["id"] == "goal-1"
    assert result["status"] == 4
    assert result["result"] is True


async def test_feedback_goes_only_to_callers_that_asked(rosbridge, token, operator):
    robot, caller = await rosbridge(token=token), await rosbridge(user=operator)
    await robot.send(op="advertise_action", action="navigate", type="nav2_msgs/NavigateToPose")
    await robot.sync()
    await caller.send(op="send_action_goal", id="g", action="/r1/navigate", action_type="a/B")
    goal = await robot.receive()
    await robot.send(op="action_feedback", action="/r1/navigate", id=goal["id"], values={})
    await robot.sync()
    assert await caller.quiet()


async def test_a_goal_can_be_cancelled(rosbridge, token, operator):
    robot, caller = await rosbridge(token=token), await rosbridge(user=operator)
    await robot.send(op="advertise_action", action="navigate", type="nav2_msgs/NavigateToPose")
    await robot.sync()
    await caller.send(op="send_action_goal", id="g", action="/r1/navigate", action_type="a/B")
    goal = await robot.receive()
    await caller.send(op="cancel_action_goal", id="g", action="/r1/navigate")
    assert await robot.receive() == {
        "op": "cancel_action_goal",
        "id": goal["id"],
        "action": "navigate",
    }


async def test_action_servers_are_listed(rosbridge, token, viewer):
    robot, watcher = await rosbridge(token=token), await rosbridge(user=viewer)
    await robot.send(op="advertise_action", action="navigate", type="nav2_msgs/NavigateToPose")
    await robot.sync()
    response = await watcher.call("/rosapi/action_servers")
    assert response["values"] == {"action_servers": ["/r1/navigate"]}
