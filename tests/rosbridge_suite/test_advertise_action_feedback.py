"""rosbridge_server/test/websocket/advertise_action_feedback.test.py"""

from __future__ import annotations


async def test_feedback(make_client, node):
    ws_client = await make_client()
    await ws_client.send_json(
        {
            "op": "advertise_action",
            "action": "/test_fibonacci_action",
            "type": "example_interfaces/Fibonacci",
        }
    )
    await ws_client.settle()
    await node.send_json(
        {
            "op": "send_action_goal",
            "id": "goal",
            "action": "/test_fibonacci_action",
            "action_type": "example_interfaces/Fibonacci",
            "args": {"order": 5},
            "feedback": True,
        }
    )
    [request] = await ws_client.expect(1)
    assert request["op"] == "send_action_goal"
    assert request["action"] == "/test_fibonacci_action"
    assert request["action_type"] == "example_interfaces/Fibonacci"
    assert request["args"] == {"order": 5}

    await ws_client.send_json(
        {
            "op": "action_feedback",
            "action": "/test_fibonacci_action",
            "values": {"sequence": [0, 1, 1, 2]},
            "id": request["id"],
        }
    )
    await ws_client.send_json(
        {
            "op": "action_result",
            "action": "/test_fibonacci_action",
            "values": {"sequence": [0, 1, 1, 2, 3, 5]},
            "status": 4,
            "id": request["id"],
            "result": True,
        }
    )
    feedback, result = await node.expect(2)
    assert feedback["values"] == {"sequence": [0, 1, 1, 2]}
    assert result["values"] == {"sequence": [0, 1, 1, 2, 3, 5]}
    assert result["status"] == 4
