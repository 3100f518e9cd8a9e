"""rosbridge_server/test/websocket/advertise_service_duplicate.test.py"""

from __future__ import annotations


async def test_double_advertise(make_client, node):
    ws_client1 = await make_client()
    await ws_client1.send_json(
        {"op": "advertise_service", "type": "std_srvs/SetBool", "service": "/test_service"}
    )
    await ws_client1.settle()
    await node.send_json(
        {"op": "call_service", "id": "c1", "service": "/test_service", "args": {"data": True}}
    )
    assert await ws_client1.expect(1) == [
        {
            "op": "call_service",
            "service": "/test_service",
            "id": "service_request:/test_service:1",
            "args": {"data": True},
        }
    ]
    await ws_client1.close()
    assert (await node.expect(1))[0]["result"] is False  # the call died with its server

    ws_client2 = await make_client()
    await ws_client2.send_json(
        {"op": "advertise_service", "type": "std_srvs/SetBool", "service": "/test_service"}
    )
    await ws_client2.settle()
    await node.send_json(
        {"op": "call_service", "id": "c2", "service": "/test_service", "args": {"data": False}}
    )
    assert await ws_client2.expect(1) == [
        {
            "op": "call_service",
            "id": "service_request:/test_service:1",
            "service": "/test_service",
            "args": {"data": False},
        }
    ]
    await ws_client2.send_json(
        {
            "op": "service_response",
            "service": "/test_service",
            "values": {"success": True, "message": "Hello world 2"},
            "id": "service_request:/test_service:1",
            "result": True,
        }
    )
    [response] = await node.expect(1)
    assert response["id"] == "c2"
    assert response["values"] == {"success": True, "message": "Hello world 2"}


async def test_a_second_advertiser_replaces_the_first(make_client, node):
    first, second = await make_client(), await make_client()
    for client in (first, second):
        await client.send_json(
            {"op": "advertise_service", "type": "std_srvs/SetBool", "service": "/test_service"}
        )
        await client.settle()
    await node.send_json({"op": "call_service", "id": "c", "service": "/test_service"})
    assert (await second.expect(1))[0]["id"] == "service_request:/test_service:1"
