"""rosbridge_server/test/websocket/advertise_service.test.py"""

from __future__ import annotations


async def test_two_concurrent_calls(make_client, node):
    ws_client = await make_client()
    await ws_client.send_json(
        {"op": "advertise_service", "type": "std_srvs/SetBool", "service": "/test_service"}
    )
    await ws_client.settle()

    for call_id, data in (("call-1", True), ("call-2", False)):
        await node.send_json(
            {
                "op": "call_service",
                "id": call_id,
                "service": "/test_service",
                "args": {"data": data},
            }
        )
    requests = await ws_client.expect(2)

    assert len(requests) == 2
    assert requests[0]["op"] == "call_service"
    assert requests[0]["service"] == "/test_service"
    assert requests[0]["args"] == {"data": True}
    await ws_client.send_json(
        {
            "op": "service_response",
            "service": "/test_service",
            "values": {"success": True, "message": "Hello world 1"},
            "id": requests[0]["id"],
            "result": True,
        }
    )
    assert requests[1]["op"] == "call_service"
    assert requests[1]["service"] == "/test_service"
    assert requests[1]["args"] == {"data": False}
    await ws_client.send_json(
        {
            "op": "service_response",
            "service": "/test_service",
            "values": {"success": True, "message": "Hello world 2"},
            "id": requests[1]["id"],
            "result": True,
        }
    )

    responses = {r["id"]: r["values"] for r in await node.expect(2)}
    assert responses == {
        "call-1": {"success": True, "message": "Hello world 1"},
        "call-2": {"success": True, "message": "Hello world 2"},
    }
