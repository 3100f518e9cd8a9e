"""rosbridge_server/test/websocket/call_service.test.py"""

from __future__ import annotations


async def test_one_call(make_client, node):
    await node.send_json(
        {"op": "advertise_service", "type": "std_srvs/SetBool", "service": "/test_service"}
    )
    await node.settle()
    ws_client = await make_client()

    await ws_client.send_json(
        {
            "op": "call_service",
            "type": "std_srvs/SetBool",
            "service": "/test_service",
            "args": {"data": True},
        }
    )
    [request] = await node.expect(1)
    assert request["args"] == {"data": True}
    await node.send_json(
        {
            "op": "service_response",
            "service": "/test_service",
            "id": request["id"],
            "values": {"success": True, "message": "Hello, world!"},
            "result": True,
        }
    )

    responses = await ws_client.expect(1)
    assert len(responses) == 1
    assert responses[0]["op"] == "service_response"
    assert responses[0]["service"] == "/test_service"
    assert responses[0]["values"] == {"success": True, "message": "Hello, world!"}
    assert responses[0]["result"] is True
