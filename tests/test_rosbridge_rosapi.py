"""rosapi answers as rosapi does, showing each caller only what it may see."""

from __future__ import annotations

import json

import pytest

from tests.conftest import make_building, make_robot

pytestmark = pytest.mark.django_db(transaction=True)


@pytest.fixture
def tokens(building):
    other = make_building(code="elsewhere", name="Elsewhere")
    return {
        "r1": make_robot(name="r1", buildings=[building])[1],
        "rx": make_robot(name="rx", buildings=[other])[1],
    }


async def publishing(rosbridge, token, topic, msg):
    robot = await rosbridge(token=token)
    await robot.send(op="publish", topic=topic, msg=msg)
    await robot.sync()
    return robot


async def test_topics_lists_visible_topics_with_their_types(rosbridge, tokens, viewer):
    await publishing(rosbridge, tokens["r1"], "map_id", {"data": "boccioni_1/Hall"})
    await publishing(rosbridge, tokens["rx"], "map_id", {"data": "elsewhere/Hall"})
    watcher = await rosbridge(user=viewer)
    response = await watcher.call("rosapi/topics")
    assert response["values"] == {"topics": ["/r1/map_id"], "types": ["std_msgs/String"]}


async def test_topic_type_and_topics_for_type(rosbridge, tokens, viewer):
    await publishing(rosbridge, tokens["r1"], "map_id", {"data": "boccioni_1/Hall"})
    watcher = await rosbridge(user=viewer)
    typed = await watcher.call("/rosapi/topic_type", {"topic": "/r1/map_id"})
    assert typed["values"] == {"type": "std_msgs/String"}
    found = await watcher.call("/rosapi/topics_for_type", {"type": "std_msgs/msg/String"})
    assert found["values"] == {"topics": ["/r1/map_id"]}


async def test_services_lists_the_servers_and_the_visible_clients(rosbridge, tokens, viewer):
    robot = await rosbridge(token=tokens["rx"])
    await robot.send(op="advertise_service", service="secret", type="std_srvs/Trigger")
    await robot.sync()
    watcher = await rosbridge(user=viewer)
    listed = (await watcher.call("/rosapi/services"))["values"]["services"]
    assert "/rosapi/topics" in listed
    assert "/cloudnav/teleop_lock" in listed
    assert "/rx/secret" not in listed


async def test_nodes_lists_the_server_and_visible_robots(rosbridge, tokens, viewer):
    await rosbridge(token=tokens["r1"])
    await rosbridge(token=tokens["rx"])
    watcher = await rosbridge(user=viewer)
    assert (await watcher.call("/rosapi/nodes"))["values"] == {"nodes": ["/cloudnav", "/r1"]}


async def test_get_time_answers_both_spellings(rosbridge, viewer):
    watcher = await rosbridge(user=viewer)
    time = (await watcher.call("/rosapi/get_time"))["values"]["time"]
    assert time["sec"] == time["secs"] > 1_700_000_000
    assert time["nanosec"] == time["nsecs"]


async def test_params_round_trip_as_json_strings(rosbridge, tokens, operator, viewer):
    robot = await rosbridge(token=tokens["r1"])
    set_ = await robot.call("/rosapi/set_param", {"name": "max_speed", "value": "0.5"})
    assert set_["values"]["successful"] is True
    watcher = await rosbridge(user=viewer)
    got = await watcher.call("/rosapi/get_param", {"name": "/r1/max_speed"})
    assert json.loads(got["values"]["value"]) == 0.5
    names = await watcher.call("/rosapi/get_param_names")
    assert names["values"] == {"names": ["/r1/max_speed"]}


async def test_get_param_of_a_missing_name_gives_the_default(rosbridge, viewer):
    watcher = await rosbridge(user=viewer)
    got = await watcher.call("/rosapi/get_param", {"name": "/nothing", "default_value": "3"})
    assert got["values"] == {"value": "3", "successful": True, "reason": ""}
    missing = await watcher.call("/rosapi/get_param", {"name": "/nothing"})
    assert missing["values"]["successful"] is False


async def test_viewers_cannot_set_params(rosbridge, viewer):
    watcher = await rosbridge(user=viewer)
    response = await watcher.call("/rosapi/set_param", {"name": "/x", "value": "1"})
    assert response["result"] is False


async def test_a_robot_cannot_read_another_buildings_params(rosbridge, tokens):
    robot = await rosbridge(token=tokens["r1"])
    await robot.call("/rosapi/set_param", {"name": "max_speed", "value": "0.5"})
    stranger = await rosbridge(token=tokens["rx"])
    response = await stranger.call("/rosapi/get_param", {"name": "/r1/max_speed"})
    assert response["result"] is False
