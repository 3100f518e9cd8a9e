"""What one rosbridge connection may make the server hold, checked on the domain modules:
frame decoding, echoed ids, subscriptions, advertisements, calls, parameters, fragments."""

from __future__ import annotations

import json

import cbor2
import pytest

from telemetry.domain.bus import SubscribeParams, TopicBus
from telemetry.domain.calls import CallTable
from telemetry.domain.decoding import FrameLimits, decode_frame
from telemetry.domain.encoding import Outgoing
from telemetry.domain.fragments import PIECE_OVERHEAD, Reassembler
from telemetry.domain.limits import ByteBudget, ConnectionLimits, Holdings
from telemetry.domain.protocol import MAX_ID_LENGTH, echoable_id, parse_op
from telemetry.exceptions import BadFrame, LimitReached
from tests.hostile import cbor_frame, cbor_head, cbor_tag, shared_reference_bomb
from tests.timers import ManualTimers

LIMITS = FrameLimits(max_bytes=2**20, max_nodes=1000, max_depth=16)


class Peer:
    def __init__(self, key: str) -> None:
        self.key = key
        self.received: list[bytes] = []

    def deliver(self, wire) -> None:
        self.received.extend(wire.payloads)


# ---------------------------------------------------------------- decoding


def test_plain_json_values_and_byte_strings_decode_from_cbor():
    frame = {"op": "publish", "msg": {"a": [1, -2, 2.5, None, True, False, "x", b"\x00\xff"]}}
    assert decode_frame(cbor2.dumps(frame), LIMITS) == frame


def test_a_frame_of_shared_references_is_refused_before_it_is_decoded():
    with pytest.raises(BadFrame, match="tag 28"):
        decode_frame(cbor_frame({"op": "x"}, id=shared_reference_bomb()), LIMITS)


SEMANTIC_TAGS = [0, 1, 2, 3, 4, 5, 21, 22, 23, 24, 25, 28, 29, 30, 32, 35, 36, 37, 256, 258, 55799]


@pytest.mark.parametrize("tag", [*SEMANTIC_TAGS, 99_999, 2**40])
def test_no_cbor_tag_is_decoded(tag):
    with pytest.raises(BadFrame, match="tag"):
        decode_frame(cbor_frame({"op": "x"}, id=cbor_tag(tag, b"\x00")), LIMITS)


@pytest.mark.parametrize(
    "item",
    [
        b"\xf7",  # undefined
        b"\xf0",  # simple value 16
        b"\xf8\x20",  # simple value 32
        b"\x5f\x41a\xff",  # indefinite byte string
        b"\x9f\x01\xff",  # indefinite array
        b"\x1c",  # reserved argument
    ],
    ids=["undefined", "simple", "simple-byte", "indefinite-bytes", "indefinite-array", "reserved"],
)
def test_cbor_beyond_json_is_refused(item):
    with pytest.raises(BadFrame):
        decode_frame(cbor_frame({"op": "x"}, id=item), LIMITS)


@pytest.mark.parametrize(
    "data",
    [
        b"\xa1\x01\x02",  # integer key
        b"\xa1\x61a\x7a\xff\xff\xff\xff",  # string longer than the frame
        b"\xa1\x61a\x9b" + b"\xff" * 8,  # array longer than the frame
        b"\xa1\x61a\x01\x00",  # bytes after the item
        b"",
    ],
    ids=["int-key", "long-string", "long-array", "trailing", "empty"],
)
def test_malformed_cbor_is_refused(data):
    with pytest.raises(BadFrame):
        decode_frame(data, LIMITS)


def test_values_past_the_budget_are_refused_in_both_formats():
    many = {"op": "publish", "msg": {"data": list(range(LIMITS.max_nodes))}}
    with pytest.raises(BadFrame, match="values"):
        decode_frame(cbor2.dumps(many), LIMITS)
    with pytest.raises(BadFrame, match="values"):
        decode_frame(json.dumps(many), LIMITS)
    fits = {"op": "publish", "msg": {"data": list(range(LIMITS.max_nodes - 4))}}
    assert decode_frame(cbor2.dumps(fits), LIMITS) == fits
    assert decode_frame(json.dumps(fits), LIMITS) == fits


def test_keys_are_not_counted_as_values():
    pairs = {"op": "x", "msg": {f"k{i}": i for i in range(LIMITS.max_nodes - 3)}}
    assert decode_frame(cbor2.dumps(pairs), LIMITS) == pairs
    assert decode_frame(json.dumps(pairs), LIMITS) == pairs


def test_nesting_past_the_depth_is_refused():
    deep = cbor_head(5, 1) + cbor2.dumps("a") + b"\x81" * LIMITS.max_depth + b"\x00"
    with pytest.raises(BadFrame, match="nested"):
        decode_frame(deep, LIMITS)
    with pytest.raises(BadFrame, match="nested"):
        decode_frame('{"a":' + "[" * 100_000 + "]" * 100_000 + "}", FrameLimits(2**20, 10**6, 16))


# ---------------------------------------------------------------- echoed ids


@pytest.mark.parametrize(
    ("value", "echoed"),
    [
        ("call-1", "call-1"),
        (7, 7),
        (-(2**63), -(2**63)),
        (2**64 - 1, 2**64 - 1),
        (2**64, None),
        ("x" * (MAX_ID_LENGTH + 1), None),
        (True, None),
        ([1, 2], None),
        ({"a": 1}, None),
        (1.5, None),
    ],
)
def test_only_a_short_string_or_a_64_bit_integer_is_echoed(value, echoed):
    assert echoable_id(value) == echoed


def test_a_frame_with_an_id_that_cannot_be_echoed_is_refused_without_it():
    with pytest.raises(BadFrame) as refused:
        parse_op({"op": "subscribe", "topic": "/a", "id": [[1], [1]]})
    assert refused.value.id is None


def test_type_names_are_bounded():
    with pytest.raises(BadFrame, match="type"):
        parse_op({"op": "advertise", "topic": "/a", "type": "t" * 1000})


# ---------------------------------------------------------------- encoding


def test_byte_strings_become_base64_in_json():
    out = Outgoing({"op": "publish", "topic": "/c", "msg": {"data": b"\x00\xff"}})
    assert json.loads(out.wire().payloads[0])["msg"]["data"] == "AP8="
    assert cbor2.loads(out.wire("cbor").payloads[0])["msg"]["data"] == b"\x00\xff"


def test_a_lone_surrogate_is_escaped_in_json_and_replaced_in_cbor():
    text = json.loads('"\\ud800!"')
    out = Outgoing({"op": "publish", "topic": "/c", "msg": {"data": text}})
    assert json.loads(out.wire().payloads[0])["msg"]["data"] == text
    assert cbor2.loads(out.wire("cbor").payloads[0])["msg"]["data"] == "\ufffd!"


# ---------------------------------------------------------------- bus and call tables


def bus(**limits: int) -> TopicBus:
    return TopicBus(ManualTimers().call_later, limits=ConnectionLimits(**limits))


def test_subscription_requests_per_connection_are_bounded():
    topics = bus(subscriptions=3)
    peer = Peer("c1")
    for n in range(3):
        topics.subscribe(peer, "/a", "std_msgs/String", SubscribeParams(), sid=f"s{n}")
    with pytest.raises(LimitReached):
        topics.subscribe(peer, "/b", "std_msgs/String", SubscribeParams(), sid="s3")
    topics.subscribe(peer, "/a", "std_msgs/String", SubscribeParams(), sid="s0")  # the same one
    topics.subscribe(Peer("c2"), "/b", "std_msgs/String", SubscribeParams())  # another peer
    topics.unsubscribe(peer, "/a", "s1")
    topics.subscribe(peer, "/b", "std_msgs/String", SubscribeParams(), sid="s3")
    assert topics.get("/b") is not None


def test_a_refused_subscription_leaves_no_topic_behind():
    topics = bus(subscriptions=1)
    peer = Peer("c1")
    topics.subscribe(peer, "/a", "std_msgs/String", SubscribeParams())
    with pytest.raises(LimitReached):
        topics.subscribe(peer, "/b", "std_msgs/String", SubscribeParams())
    assert topics.get("/b") is None


def test_advertisements_and_topics_published_count_together():
    topics = bus(advertisements=2)
    peer = Peer("c1")
    topics.advertise(peer, "/a", "std_msgs/String")
    topics.advertise(peer, "/b", "std_msgs/String")
    topics.advertise(Peer("c2"), "/c", "std_msgs/String")
    with pytest.raises(LimitReached):
        topics.publish(peer, "/c", {"data": "x"})
    topics.unadvertise(peer, "/a")
    topics.publish(peer, "/c", {"data": "x"})


def test_latched_messages_a_connection_leaves_behind_are_bounded_in_bytes():
    topics = bus(latched_bytes=1000)
    peer = Peer("c1")
    topics.advertise(peer, "/a", "std_msgs/String", latch=True)
    topics.advertise(peer, "/b", "std_msgs/String", latch=True)
    topics.publish(peer, "/a", {"data": "x"}, size=600)
    topics.publish(peer, "/a", {"data": "y"}, size=900)  # replaces its own
    with pytest.raises(LimitReached):
        topics.publish(peer, "/b", {"data": "z"}, size=200)
    topics.publish(peer, "/b", {"data": "z"}, size=100)
    topics.unadvertise(peer, "/a")
    topics.publish(peer, "/b", {"data": "w"}, size=1000)


def test_a_dropped_peer_gets_its_whole_allowance_back():
    topics = bus(subscriptions=1, advertisements=1)
    peer = Peer("c1")
    topics.subscribe(peer, "/a", "std_msgs/String", SubscribeParams())
    topics.advertise(peer, "/b", "std_msgs/String")
    topics.drop(peer)
    topics.subscribe(peer, "/c", "std_msgs/String", SubscribeParams())
    topics.advertise(peer, "/d", "std_msgs/String")


def test_advertised_services_and_waiting_calls_per_connection_are_bounded():
    table = CallTable("service_request", ConnectionLimits(services=2, pending_calls=2))
    provider, caller = Peer("p"), Peer("c")
    table.advertise("/s1", "T", provider)
    table.advertise("/s2", "T", provider)
    table.advertise("/s2", "T", provider)  # again: the same name
    with pytest.raises(LimitReached):
        table.advertise("/s3", "T", provider)
    served = table.provider("/s1")
    assert served is not None
    first = table.start(served, caller, "a")
    table.start(served, caller, "b")
    with pytest.raises(LimitReached):
        table.start(served, caller, "c")
    table.finish("/s1", provider, first.request_id)
    table.start(served, caller, "c")
    table.unadvertise("/s1", provider)
    table.advertise("/s3", "T", provider)


def test_parameter_holdings_are_bounded_by_count_and_bytes():
    held = Holdings("parameters", max_count=2, max_bytes=100)
    held.take("c1", "/a", 40)
    held.take("c1", "/a", 60)  # replaces
    with pytest.raises(LimitReached):
        held.take("c1", "/b", 41)
    held.take("c1", "/b", 40)
    with pytest.raises(LimitReached):
        held.take("c1", "/c", 0)
    held.take("c2", "/c", 100)
    assert sorted(held.drop("c1")) == ["/a", "/b"]
    held.take("c1", "/c", 100)


# ---------------------------------------------------------------- fragments


def pieces(text: str, size: int) -> list[str]:
    return [text[i : i + size] for i in range(0, len(text), size)]


def test_fragments_past_the_connection_budget_are_refused_and_forgotten():
    shared = ByteBudget(10**6)
    joiner = Reassembler(3 * (PIECE_OVERHEAD + 10), shared, ManualTimers().call_later)
    for num in range(3):
        joiner.add("f", num, 9, "x" * 10)
    with pytest.raises(LimitReached):
        joiner.add("f", 3, 9, "x" * 10)
    assert joiner.held == 0
    assert shared.used == 0


def test_fragments_of_all_connections_share_one_budget():
    shared = ByteBudget(2 * (PIECE_OVERHEAD + 10))
    first = Reassembler(10**6, shared, ManualTimers().call_later)
    second = Reassembler(10**6, shared, ManualTimers().call_later)
    first.add("f", 0, 2, "x" * 10)
    first.add("g", 0, 2, "x" * 10)
    with pytest.raises(LimitReached):
        second.add("f", 0, 2, "x" * 10)
    first.clear()
    second.add("f", 0, 2, "x" * 10)
    assert shared.used == PIECE_OVERHEAD + 10


def test_a_message_left_incomplete_expires_on_a_timer_without_another_fragment():
    timers = ManualTimers()
    shared = ByteBudget(10**6)
    joiner = Reassembler(10**6, shared, timers.call_later, timeout=10.0)
    joiner.add("f", 0, 2, "x" * 10)
    timers.advance(9.0)
    joiner.add("g", 0, 2, "y" * 10)
    timers.advance(1.5)
    assert shared.used == PIECE_OVERHEAD + 10  # "f" went; "g" is still young
    timers.advance(10.0)
    assert shared.used == 0
    assert joiner.held == 0
    assert timers.armed == 0


def test_a_completed_message_gives_its_budget_back_and_cancels_its_timer():
    timers = ManualTimers()
    shared = ByteBudget(10**6)
    joiner = Reassembler(10**6, shared, timers.call_later)
    text = json.dumps({"op": "publish", "topic": "/a", "msg": {"data": "z" * 50}})
    parts = pieces(text, 16)
    results = [joiner.add("f", n, len(parts), p) for n, p in enumerate(parts)]
    assert results[-1] == text
    assert shared.used == 0
    assert timers.armed == 0


def test_wide_characters_count_for_their_memory():
    shared = ByteBudget(10**6)
    joiner = Reassembler(PIECE_OVERHEAD + 100, shared, ManualTimers().call_later)
    joiner.add("f", 0, 3, "a" * 100)
    joiner.clear()
    with pytest.raises(LimitReached):
        joiner.add("f", 0, 3, "\u20ac" * 100)
