"""How long a parameter lives, and how many one connection may set.

An admin's parameters persist (the building's configuration, as on ROS 1's parameter
server); a robot's or an operator's live as long as the connection that set them, as a
ROS 2 node's parameters live with the node.
"""

from __future__ import annotations

import pytest

pytestmark = pytest.mark.django_db(transaction=True)


async def value_of(client, name):
    answer = await client.call("/rosapi/get_param", {"name": name}, id=f"get {name}")
    return answer["values"]["value"] if answer["values"]["successful"] else None


async def test_a_robots_parameters_go_when_its_connection_closes(rosbridge, token, viewer):
    robot, watcher = await rosbridge(token=token), await rosbridge(user=viewer)
    await robot.call("/rosapi/set_param", {"name": "max_speed", "value": "0.5"})
    assert await value_of(watcher, "/r1/max_speed") == "0.5"
    await robot.close()
    assert await value_of(watcher, "/r1/max_speed") is None


async def test_an_operators_parameters_go_when_its_connection_closes(
    rosbridge, token, operator, viewer
):
    person, watcher = await rosbridge(user=operator), await rosbridge(user=viewer)
    await person.call("/rosapi/set_param", {"name": "/r1/max_speed", "value": "0.3"})
    assert await value_of(watcher, "/r1/max_speed") == "0.3"
    await person.close()
    assert await value_of(watcher, "/r1/max_speed") is None


async def test_an_admins_parameters_persist(rosbridge, admin, viewer):
    person, watcher = await rosbridge(user=admin), await rosbridge(user=viewer)
    await person.call("/rosapi/set_param", {"name": "/fleet/speed_limit", "value": "1.2"})
    await person.close()
    assert await value_of(watcher, "/fleet/speed_limit") == "1.2"


async def test_a_parameter_an_admin_took_over_outlives_the_connection_that_set_it_first(
    rosbridge, token, admin, viewer
):
    robot, person = await rosbridge(token=token), await rosbridge(user=admin)
    watcher = await rosbridge(user=viewer)
    await robot.call("/rosapi/set_param", {"name": "max_speed", "value": "0.5"})
    await person.call("/rosapi/set_param", {"name": "/r1/max_speed", "value": "0.4"})
    await robot.close()
    assert await value_of(watcher, "/r1/max_speed") == "0.4"


async def test_a_connection_sets_at_most_its_share_of_parameters(rosbridge, token, settings):
    settings.CLOUDNAV_ROSBRIDGE_MAX_PARAMS = 3
    robot = await rosbridge(token=token)
    for n in range(3):
        answer = await robot.call("/rosapi/set_param", {"name": f"p{n}", "value": "1"})
        assert answer["result"] is True
    refused = await robot.call("/rosapi/set_param", {"name": "p3", "value": "1"})
    assert refused["result"] is False
    assert "parameters" in refused["values"]
    again = await robot.call("/rosapi/set_param", {"name": "p0", "value": "2"})
    assert again["result"] is True
    await robot.call("/rosapi/delete_param", {"name": "p1"})
    freed = await robot.call("/rosapi/set_param", {"name": "p3", "value": "1"})
    assert freed["result"] is True


async def test_parameter_bytes_of_a_connection_are_bounded(rosbridge, token, settings):
    settings.CLOUDNAV_ROSBRIDGE_MAX_PARAM_BYTES = 1000
    robot = await rosbridge(token=token)
    big = '"' + "x" * 2000 + '"'
    refused = await robot.call("/rosapi/set_param", {"name": "blob", "value": big})
    assert refused["result"] is False
    assert "bytes" in refused["values"]
