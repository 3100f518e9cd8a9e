"""Topic operations behave as rosbridge_suite's: advertise, publish, subscribe and friends."""

from __future__ import annotations

import json
from typing import Any

import pytest

from telemetry.domain.limits import ConnectionLimits

pytestmark = pytest.mark.django_db(transaction=True)

POSE = {
    "header": {
        "frame_id": "boccioni_1/CorridorA",
        "stamp": {"sec": 1, "nanosec": 2, "secs": 1, "nsecs": 2},
    },
    "pose": {"position": {"x": 1.0, "y": 2.0, "z": 0.0}, "orientation": {"w": 1.0}},
}


MIN_FRAGMENT = ConnectionLimits().min_fragment_size


async def test_a_robot_publishes_its_pose_to_an_operator(rosbridge, token, operator):
    robot, watcher = await rosbridge(token=token), await rosbridge(user=operator)
    await watcher.send(op="subscribe", topic="/r1/pose", type="geometry_msgs/PoseStamped")
    await watcher.sync()
    await robot.send(op="publish", topic="pose", msg=POSE)
    assert await watcher.receive() == {"op": "publish", "topic": "/r1/pose", "msg": POSE}


async def test_a_publisher_gets_its_own_messages_back(rosbridge, token):
    robot = await rosbridge(token=token)
    await robot.send(op="subscribe", topic="pose")
    await robot.send(op="publish", topic="/r1/pose", msg=POSE)
    assert (await robot.receive())["topic"] == "pose"


async def test_publish_advertises_a_known_topic_implicitly(rosbridge, token, admin):
    robot, watcher = await rosbridge(token=token), await rosbridge(user=admin)
    await robot.send(op="publish", topic="odom", msg={"x": 1})
    await robot.sync()
    listed = await watcher.call("/rosapi/topics")
    assert ("/r1/odom", "nav_msgs/Odometry") in zip(
        listed["values"]["topics"], listed["values"]["types"], strict=True
    )


async def test_publish_to_an_unknown_topic_is_dropped(rosbridge, token):
    robot = await rosbridge(token=token)
    await robot.send(op="set_level", level="error")
    await robot.send(op="publish", topic="mystery", msg={"data": 1})
    status = await robot.receive()
    assert status["op"] == "status"
    assert "/r1/mystery" in status["msg"]


async def test_an_advertised_topic_reaches_subscribers(rosbridge, token, operator):
    robot, watcher = await rosbridge(token=token), await rosbridge(user=operator)
    await robot.send(op="advertise", topic="battery", type="std_msgs/Float32")
    await watcher.send(op="subscribe", topic="/r1/battery")
    await watcher.sync()
    await robot.send(op="publish", topic="battery", msg={"data": 0.5})
    assert (await watcher.receive())["msg"] == {"data": 0.5}


async def test_a_type_conflict_is_dropped(rosbridge, token):
    robot = await rosbridge(token=token)
    await robot.send(op="set_level", level="error")
    await robot.send(op="advertise", topic="pose", type="std_msgs/String")
    assert "type" in (await robot.receive())["msg"]


async def test_ros2_type_spelling_matches_ros1(rosbridge, token):
    robot = await rosbridge(token=token)
    await robot.send(op="set_level", level="error")
    await robot.send(op="advertise", topic="pose", type="geometry_msgs/msg/PoseStamped")
    assert await robot.nothing_more()


async def test_unsubscribe_by_id_keeps_the_other_subscriptions(rosbridge, token):
    robot = await rosbridge(token=token)
    await robot.send(op="subscribe", topic="pose", id="a")
    await robot.send(op="subscribe", topic="pose", id="b")
    await robot.send(op="unsubscribe", topic="pose", id="a")
    await robot.send(op="publish", topic="pose", msg=POSE)
    assert (await robot.receive())["op"] == "publish"
    await robot.send(op="unsubscribe", topic="pose", id="b")
    await robot.send(op="publish", topic="pose", msg=POSE)
    assert await robot.nothing_more()


async def test_two_subscriptions_on_one_connection_deliver_once(rosbridge, token):
    robot = await rosbridge(token=token)
    await robot.send(op="subscribe", topic="pose", id="a")
    await robot.send(op="subscribe", topic="pose", id="b")
    await robot.send(op="publish", topic="pose", msg=POSE)
    assert (await robot.receive())["op"] == "publish"
    assert await robot.nothing_more()


async def test_unsubscribe_without_id_removes_every_subscription(rosbridge, token):
    robot = await rosbridge(token=token)
    await robot.send(op="subscribe", topic="pose", id="a")
    await robot.send(op="subscribe", topic="pose", id="b")
    await robot.send(op="unsubscribe", topic="pose")
    await robot.send(op="publish", topic="pose", msg=POSE)
    assert await robot.nothing_more()


async def test_a_latched_topic_is_replayed_to_new_subscribers(rosbridge, token, viewer):
    robot = await rosbridge(token=token)
    await robot.send(op="publish", topic="map_id", msg={"data": "boccioni_1/CorridorA"})
    await robot.sync()
    for _ in range(2):
        watcher = await rosbridge(user=viewer)
        await watcher.send(op="subscribe", topic="/r1/map_id", type="std_msgs/String")
        assert (await watcher.receive())["msg"] == {"data": "boccioni_1/CorridorA"}


async def test_a_publisher_can_ask_for_latching(rosbridge, token, viewer):
    robot = await rosbridge(token=token)
    await robot.send(op="advertise", topic="mode", type="std_msgs/String", latch=True)
    await robot.send(op="publish", topic="mode", msg={"data": "docked"})
    await robot.sync()
    watcher = await rosbridge(user=viewer)
    await watcher.send(op="subscribe", topic="/r1/mode")
    assert (await watcher.receive())["msg"] == {"data": "docked"}


async def test_the_latched_message_goes_with_its_last_publisher(rosbridge, token, viewer):
    robot = await rosbridge(token=token)
    await robot.send(op="publish", topic="map_id", msg={"data": "boccioni_1/CorridorA"})
    await robot.close()
    watcher = await rosbridge(user=viewer)
    await watcher.send(op="subscribe", topic="/r1/map_id", type="std_msgs/String")
    assert await watcher.nothing_more()


async def test_throttle_rate_drops_messages_in_between(rosbridge, token):
    robot = await rosbridge(token=token)
    await robot.send(op="subscribe", topic="pose", throttle_rate=10_000)
    for _ in range(5):
        await robot.send(op="publish", topic="pose", msg=POSE)
    assert (await robot.receive())["op"] == "publish"
    assert await robot.nothing_more()


async def test_queue_length_keeps_the_newest_while_throttled(rosbridge, token):
    robot = await rosbridge(token=token)
    await robot.send(op="subscribe", topic="odom", throttle_rate=50, queue_length=2)
    for n in range(5):
        await robot.send(op="publish", topic="odom", msg={"n": n})
    received = [(await robot.receive())["msg"]["n"] for _ in range(3)]
    assert received == [0, 3, 4]
    assert await robot.nothing_more(0.2)


async def test_fragment_size_splits_messages_with_integer_totals(rosbridge, token):
    robot = await rosbridge(token=token)
    await robot.send(op="subscribe", topic="odom", fragment_size=MIN_FRAGMENT)
    msg = {"data": "z" * (3 * MIN_FRAGMENT)}
    await robot.send(op="publish", topic="odom", msg=msg)
    first = await robot.receive()
    assert first["op"] == "fragment"
    assert isinstance(first["total"], int)
    assert first["num"] == 0
    pieces = [first] + [await robot.receive() for _ in range(first["total"] - 1)]
    assert [p["num"] for p in pieces] == list(range(first["total"]))
    assert all(len(p["data"]) <= MIN_FRAGMENT for p in pieces)
    whole = json.loads("".join(p["data"] for p in pieces))
    assert whole == {"op": "publish", "topic": "odom", "msg": msg}


async def test_a_fragment_size_below_the_least_gets_the_least_and_a_warning(rosbridge, token):
    robot = await rosbridge(token=token)
    await robot.send(op="set_level", level="warning")
    await robot.send(op="subscribe", topic="odom", fragment_size=1)
    warning = await robot.receive()
    assert warning["level"] == "warning"
    assert f"using {MIN_FRAGMENT}" in warning["msg"]
    await robot.send(op="publish", topic="odom", msg={"data": "z" * (2 * MIN_FRAGMENT)})
    first = await robot.receive()
    assert first["total"] == 3
    assert len(first["data"]) == MIN_FRAGMENT


async def test_cbor_compression_sends_binary_frames(rosbridge, token):
    robot = await rosbridge(token=token)
    await robot.send(op="subscribe", topic="pose", compression="cbor")
    await robot.send(op="publish", topic="pose", msg=POSE)
    raw = await robot.receive_raw()
    assert raw.get("bytes")
    assert raw.get("text") is None
    import cbor2

    assert cbor2.loads(raw["bytes"]) == {"op": "publish", "topic": "pose", "msg": POSE}


async def test_incoming_fragments_are_reassembled(rosbridge, token):
    robot = await rosbridge(token=token)
    await robot.send(op="subscribe", topic="pose")
    text = json.dumps({"op": "publish", "topic": "pose", "msg": POSE})
    pieces = [text[i : i + 25] for i in range(0, len(text), 25)]
    for num, piece in enumerate(pieces):
        await robot.send(op="fragment", id="f1", data=piece, num=num, total=len(pieces))
    assert (await robot.receive())["msg"] == POSE


async def test_messages_carry_the_topic_as_the_subscriber_spelled_it(rosbridge, token, operator):
    robot, watcher = await rosbridge(token=token), await rosbridge(user=operator)
    await robot.send(op="subscribe", topic="cmd_vel")
    await robot.send(op="subscribe", topic="pose")
    await watcher.send(op="subscribe", topic="/r1/pose")
    await watcher.sync()
    await robot.send(op="publish", topic="pose", msg=POSE)
    assert (await robot.receive())["topic"] == "pose"
    assert (await watcher.receive())["topic"] == "/r1/pose"


@pytest.mark.parametrize("spelling", [{"secs": 5, "nsecs": 6}, {"sec": 5, "nanosec": 6}])
async def test_header_stamps_reach_subscribers_in_both_spellings(rosbridge, token, spelling):
    robot = await rosbridge(token=token)
    await robot.send(op="subscribe", topic="pose")
    await robot.send(op="publish", topic="pose", msg={**POSE, "header": {"stamp": spelling}})
    stamp = (await robot.receive())["msg"]["header"]["stamp"]
    assert stamp == {"sec": 5, "nanosec": 6, "secs": 5, "nsecs": 6}


async def test_the_publish_path_reads_the_database_once_per_connection_and_topic(
    rosbridge, token, operator, monkeypatch
):
    from telemetry.access import decisions

    lookups = []
    owner_named = decisions.owner_named

    def counted(seg: str) -> Any:
        lookups.append(seg)
        return owner_named(seg)

    monkeypatch.setattr(decisions, "owner_named", counted)
    robot, watcher = await rosbridge(token=token), await rosbridge(user=operator)
    await watcher.send(op="subscribe", topic="/r1/goal")
    await watcher.sync()
    for _ in range(20):
        await watcher.send(op="publish", topic="/r1/goal", msg=POSE)
        await robot.send(op="publish", topic="pose", msg=POSE)
    await watcher.sync()
    await robot.sync()
    assert lookups == ["r1"]  # the operator's first use of r1's names; the robot knows itself
