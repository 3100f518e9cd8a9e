"""rosbridge_server/test/websocket/transient_local_publisher.test.py (latched replay)"""

from __future__ import annotations


async def test_transient_local_publisher(make_client, node):
    await node.send_json(
        {"op": "advertise", "topic": "/a_topic", "type": "std_msgs/String", "latch": True}
    )
    await node.send_json({"op": "publish", "topic": "/a_topic", "msg": {"data": "hello"}})
    await node.settle()

    for _ in range(3):
        ws_client = await make_client()
        await ws_client.send_json(
            {"op": "subscribe", "topic": "/a_topic", "type": "std_msgs/String"}
        )
        assert await ws_client.expect(1) == [
            {"op": "publish", "topic": "/a_topic", "msg": {"data": "hello"}}
        ]
