"""The rosbridge domain modules on their own: no Django, no sockets."""

from __future__ import annotations

import json

import pytest

from cloudnav_core import topics
from cloudnav_core.times import parse_stamp, stamp
from telemetry.domain import names
from telemetry.domain.bus import SubscribeParams, TopicBus
from telemetry.domain.encoding import Outgoing, Wire, to_json, ws_frame
from telemetry.domain.fragments import PIECE_OVERHEAD, Reassembler, split
from telemetry.domain.limits import ByteBudget
from telemetry.domain.outbox import Outbox
from telemetry.exceptions import InvalidName, LimitReached, TypeConflict
from tests.timers import ManualTimers


def wire(size: int) -> Wire:
    return Wire((b"x" * size,), binary=False)


def test_the_outbox_drops_the_oldest_past_its_frame_bound():
    box = Outbox(max_frames=3, max_bytes=10**9)
    frames = [wire(1) for _ in range(5)]
    for frame in frames:
        box.push(frame)
    assert [box.pop() for _ in range(3)] == frames[2:]
    assert box.dropped == 2


def test_the_outbox_drops_the_oldest_past_its_byte_bound_but_keeps_the_newest():
    box = Outbox(max_frames=100, max_bytes=250)
    for _ in range(3):
        box.push(wire(100))
    assert (len(box), box.nbytes) == (2, 200)
    box.push(wire(1000))
    assert (len(box), box.nbytes) == (1, 1000)


@pytest.mark.parametrize(
    ("name", "namespace", "expected"),
    [
        ("rosapi/topics", "", "/rosapi/topics"),
        ("rosapi/topics", "/r1", "/rosapi/topics"),
        ("cloudnav/route", "/r1", "/cloudnav/route"),
        ("pose", "/r1", "/r1/pose"),
        ("camera/image/compressed", "/r1", "/r1/camera/image/compressed"),
        ("/r2/pose", "/r1", "/r2/pose"),
        ("/trailing/", "", "/trailing"),
    ],
)
def test_names_are_made_absolute(name, namespace, expected):
    assert names.absolute(name, namespace) == expected


@pytest.mark.parametrize(
    "name", ["", "~private", "a//b", "9lives", "has space", "a/-b", 5, "/r1/pose\n", "pose\n"]
)
def test_invalid_names_are_refused(name):
    with pytest.raises(InvalidName):
        names.absolute(name)


def test_each_topic_has_its_own_redis_channel_that_names_it_back():
    channel = names.topic_channel("/r1/camera/image/compressed", 7)
    assert channel == "cloudnav:rb:7:topic:/r1/camera/image/compressed"
    assert names.topic_of_channel(channel) == "/r1/camera/image/compressed"
    assert names.topic_channel("/r1/pose", 7) != names.topic_channel("/r1/pose", 8)


@pytest.mark.parametrize("value", [{"sec": 3, "nanosec": 5}, {"secs": 3, "nsecs": 5}])
def test_times_are_read_in_both_spellings(value):
    assert parse_stamp(value) == (3, 5)


def test_times_are_written_in_both_spellings():
    assert stamp(3, 5) == {"sec": 3, "nanosec": 5, "secs": 3, "nsecs": 5}


def test_a_time_without_either_spelling_is_refused():
    with pytest.raises(ValueError, match="sec"):
        parse_stamp({"seconds": 1})


def test_fragments_have_integer_totals_and_reassemble():
    text = json.dumps({"op": "publish", "topic": "/t", "msg": {"data": "z" * 100}})
    pieces = split(text, 16, "f")
    assert all(isinstance(p["total"], int) and p["total"] == len(pieces) for p in pieces)
    joiner = Reassembler(10_000, ByteBudget(10_000), ManualTimers().call_later)
    results = [joiner.add("f", p["num"], p["total"], p["data"]) for p in reversed(pieces)]
    assert results[-1] == text
    assert results[:-1] == [None] * (len(pieces) - 1)


def test_reassembly_refuses_oversized_messages():
    joiner = Reassembler(PIECE_OVERHEAD * 2 + 10, ByteBudget(10_000), ManualTimers().call_later)
    joiner.add("f", 0, 3, "12345")
    with pytest.raises(LimitReached):
        joiner.add("f", 1, 3, "678901")


def test_nan_becomes_null_as_in_rosbridge_json():
    assert to_json({"a": float("nan"), "b": [float("inf"), 1.5]}) == '{"a":null,"b":[null,1.5]}'


def test_server_frames_are_unmasked_rfc6455_frames():
    assert ws_frame(b"hi", binary=False) == b"\x81\x02hi"
    assert ws_frame(b"x" * 300, binary=True)[:4] == b"\x82\x7e\x01\x2c"
    assert ws_frame(b"x" * 70000, binary=True)[:2] == b"\x82\x7f"


def test_a_message_is_encoded_once_per_variant():
    out = Outgoing({"op": "publish", "topic": "/t", "msg": {"data": 1}})
    assert out.wire() is out.wire()
    assert out.wire("cbor") is not out.wire()
    assert out.wire(topic="t") is not out.wire()


class Peer:
    def __init__(self, key):
        self.key = key
        self.got = []

    def deliver(self, wire):
        self.got.append(wire)


class Timers:
    def __init__(self):
        self.pending = []

    def __call__(self, _delay, callback):
        self.pending.append(callback)
        return self

    def cancel(self):
        pass

    def fire(self):
        callbacks, self.pending = self.pending, []
        for callback in callbacks:
            callback()


def test_fan_out_encodes_once_for_many_subscribers():
    bus = TopicBus(scheduler=Timers(), type_hint=topics.ROBOT_TOPIC_TYPES.get)
    peers = [Peer(f"p{n}") for n in range(50)]
    for peer in peers:
        bus.subscribe(peer, "/r1/pose", "geometry_msgs/PoseStamped", SubscribeParams())
    bus.publish(None, "/r1/pose", {"pose": {}})
    assert len({id(peer.got[0]) for peer in peers}) == 1


def test_a_topic_keeps_its_type():
    bus = TopicBus(scheduler=Timers())
    bus.advertise(Peer("a"), "/t", "std_msgs/String")
    with pytest.raises(TypeConflict):
        bus.subscribe(Peer("b"), "/t", "std_msgs/Int32", SubscribeParams())


def test_queued_messages_are_released_at_the_throttle_rate():
    clock = [0.0]
    timers = Timers()
    bus = TopicBus(scheduler=timers, clock=lambda: clock[0])
    peer = Peer("a")
    bus.subscribe(peer, "/t", "std_msgs/Int32", SubscribeParams(throttle_rate=100, queue_length=1))
    for n in range(3):
        bus.publish(None, "/t", {"data": n})
    assert len(peer.got) == 1
    clock[0] = 0.1
    timers.fire()
    assert [json.loads(w.payloads[0])["msg"]["data"] for w in peer.got] == [0, 2]
