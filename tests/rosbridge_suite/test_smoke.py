"""rosbridge_server/test/websocket/smoke.test.py"""

from __future__ import annotations

NUM_MSGS = 10
A_TOPIC, B_TOPIC = "/a_topic", "/b_topic"
A_STRING, B_STRING = "A" * 10, "B" * 10


async def test_smoke(make_client, node):
    ws_client = await make_client()
    await node.send_json({"op": "subscribe", "topic": A_TOPIC, "type": "std_msgs/String"})
    await node.send_json({"op": "advertise", "topic": B_TOPIC, "type": "std_msgs/String"})
    await node.settle()
    await ws_client.send_json(
        {"op": "subscribe", "topic": B_TOPIC, "type": "std_msgs/String", "queue_length": 0}
    )
    await ws_client.send_json({"op": "advertise", "topic": A_TOPIC, "type": "std_msgs/String"})
    await ws_client.settle()
    await ws_client.send_json(
        {"op": "publish", "topic": A_TOPIC, "msg": {"data": A_STRING}}, times=NUM_MSGS
    )
    await node.send_json({"op": "publish", "topic": B_TOPIC, "msg": {"data": B_STRING}}, NUM_MSGS)

    ws_received = await ws_client.expect(NUM_MSGS)
    ros_received = await node.expect(NUM_MSGS)
    for msg in ws_received:
        assert msg["op"] == "publish"
        assert msg["topic"] == B_TOPIC
        assert msg["msg"]["data"] == B_STRING
    assert len(ws_received) == NUM_MSGS
    assert [msg["msg"]["data"] for msg in ros_received] == [A_STRING] * NUM_MSGS
