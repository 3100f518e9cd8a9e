"""rosbridge_server/test/websocket/multiple_subscribers.test.py"""

from __future__ import annotations


async def test_multiple_subscribers(make_client, node):
    ws_client1 = await make_client()
    await ws_client1.send_json({"op": "subscribe", "topic": "/a_topic", "type": "std_msgs/String"})
    ws_client2 = await make_client()
    await ws_client2.send_json({"op": "subscribe", "topic": "/a_topic", "type": "std_msgs/String"})
    await ws_client1.settle()
    await ws_client2.settle()

    await node.send_json({"op": "publish", "topic": "/a_topic", "msg": {"data": "hello"}})

    expected = [{"op": "publish", "topic": "/a_topic", "msg": {"data": "hello"}}]
    assert await ws_client1.expect(1) == expected
    assert await ws_client2.expect(1) == expected
