"""Taps of the topic bus: the one way for the server's own features (recording, mapping,
map upkeep) to read a topic's messages (``hub.tap``, ``telemetry.domain.bus``)."""

from __future__ import annotations

from typing import Any

from telemetry.domain.bus import EVERY_TOPIC, SubscribeParams, Topic, TopicBus, TopicTap


class Peer:
    def __init__(self, key: str) -> None:
        self.key = key
        self.got: list[Any] = []

    def deliver(self, wire: Any) -> None:
        self.got.append(wire)


class Listener:
    """What the bus tells the relay (scaled mode)."""

    def __init__(self) -> None:
        self.interests: list[tuple[str, bool]] = []

    def published(self, topic: Any, msg: Any) -> None:
        pass

    def interest(self, topic: str, interested: bool) -> None:
        self.interests.append((topic, interested))

    def publishers_changed(self, topic: Any) -> None:
        pass


def make_bus() -> TopicBus:
    return TopicBus(scheduler=lambda _delay, _callback: None)  # type: ignore[arg-type,return-value]


def test_a_tap_sees_its_topics_messages_published_here_until_closed() -> None:
    bus, robot = make_bus(), Peer("robot")
    seen: list[tuple[str, Any]] = []
    tap = bus.tap("/r1/scan", lambda topic, msg: seen.append((topic.name, msg)))
    bus.advertise(robot, "/r1/scan", "sensor_msgs/LaserScan")
    bus.advertise(robot, "/r1/other", "std_msgs/String")
    bus.publish(robot, "/r1/scan", {"n": 1})
    bus.publish(None, "/r1/scan", {"n": 2})  # the server's own
    bus.publish(robot, "/r1/other", {"n": 3})
    tap.close()
    tap.close()  # closing twice does nothing
    bus.publish(robot, "/r1/scan", {"n": 4})
    assert seen == [("/r1/scan", {"n": 1}), ("/r1/scan", {"n": 2})]


def test_a_tap_of_every_topic_sees_the_topic_with_its_type() -> None:
    bus, robot = make_bus(), Peer("robot")
    seen: list[tuple[str, str | None]] = []
    bus.tap(EVERY_TOPIC, lambda topic, _msg: seen.append((topic.name, topic.type)))
    bus.advertise(robot, "/r1/a", "std_msgs/String")
    bus.advertise(robot, "/r1/b", "std_msgs/Int32")
    bus.publish(robot, "/r1/a", {"data": "x"})
    bus.publish(robot, "/r1/b", {"data": 1})
    assert seen == [("/r1/a", "std_msgs/String"), ("/r1/b", "std_msgs/Int32")]


def test_a_tap_sees_another_process_message_only_for_local_subscribers() -> None:
    bus = make_bus()
    seen: list[Any] = []
    bus.tap("/r1/pose", lambda _topic, msg: seen.append(msg))
    bus.receive_remote("/r1/pose", "geometry_msgs/PoseStamped", {"n": 1}, False)
    bus.subscribe(Peer("viewer"), "/r1/pose", "geometry_msgs/PoseStamped", SubscribeParams())
    bus.receive_remote("/r1/pose", "geometry_msgs/PoseStamped", {"n": 2}, False)
    assert seen == [{"n": 2}]


def test_a_tap_is_no_interest_in_other_processes_messages() -> None:
    bus, listener = make_bus(), Listener()
    bus.listener = listener
    tap = bus.tap("/t", lambda _topic, _msg: None)
    tap.close()
    assert listener.interests == []


def test_a_failing_tap_is_logged_and_the_message_still_reaches_everyone(caplog: Any) -> None:
    bus = make_bus()
    seen: list[Any] = []

    def broken(_topic: Topic, _msg: Any) -> None:
        raise RuntimeError("boom")

    bus.tap("/t", broken)
    bus.tap("/t", lambda _topic, msg: seen.append(msg))
    publisher, subscriber = Peer("p"), Peer("s")
    bus.advertise(publisher, "/t", "std_msgs/String")
    bus.subscribe(subscriber, "/t", None, SubscribeParams())
    bus.publish(publisher, "/t", {"data": "x"})
    assert seen == [{"data": "x"}]
    assert len(subscriber.got) == 1
    assert "a tap of /t failed" in caplog.text


def test_a_tap_may_close_itself_while_it_is_called() -> None:
    bus, robot = make_bus(), Peer("robot")
    seen: list[Any] = []
    taps: list[TopicTap] = []

    def once(_topic: Topic, msg: Any) -> None:
        seen.append(msg)
        taps[0].close()

    taps.append(bus.tap("/t", once))
    bus.advertise(robot, "/t", "std_msgs/String")
    bus.publish(robot, "/t", {"n": 1})
    bus.publish(robot, "/t", {"n": 2})
    assert seen == [{"n": 1}]
