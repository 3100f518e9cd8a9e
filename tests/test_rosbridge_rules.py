"""Fleet rules, persona by persona, for every rosbridge behaviour that needs a permission.

Each behaviour is tried by admin, operator, viewer, outsider, an unregistered robot, a robot
of another building, a robot of the same building, and the robot itself where it matters.
Outsiders and unregistered robots never get a connection at all.

The core behaviours run in the embedded mode and again across two server processes in
scaled mode (``ACROSS_PROCESSES``: the robot on one process, everyone else on the other):
the same rules hold, whichever process answers.
"""

from __future__ import annotations

from types import SimpleNamespace

import pytest

from tests.conftest import make_building, make_robot, make_submap
from tests.fixtures_live import Refused

pytestmark = pytest.mark.django_db(transaction=True)

REFUSED = "refused"
ALL = ["admin", "operator", "viewer", "outsider", "unregistered", "foreign_robot", "peer_robot"]
TWIST = {"linear": {"x": 0.2, "y": 0.0, "z": 0.0}, "angular": {"x": 0.0, "y": 0.0, "z": 0.0}}
# In the middle of the sub-map the fleet's building has (goals are checked where they are sent).
GOAL = {"header": {"frame_id": "boccioni_1/CorridorA"}, "pose": {"position": {"x": 1, "y": 0.75}}}


@pytest.fixture
def fleet(building, admin, operator, viewer, outsider):
    make_submap(building, code="CorridorA")
    other = make_building(code="elsewhere", name="Elsewhere")
    tokens = {
        "r1": make_robot(name="r1", buildings=[building])[1],
        "peer_robot": make_robot(name="r2", buildings=[building])[1],
        "foreign_robot": make_robot(name="rx", buildings=[other])[1],
        "unregistered": "cnr_unregistered",
    }
    people = {"admin": admin, "operator": operator, "viewer": viewer, "outsider": outsider}
    return SimpleNamespace(tokens=tokens, people=people)


ACROSS_PROCESSES = pytest.mark.parametrize(
    "mode",
    ["embedded", pytest.param("two processes", marks=[pytest.mark.scaled, pytest.mark.live])],
    indirect=True,
)


@pytest.fixture
def mode(request):
    return getattr(request, "param", "embedded")


@pytest.fixture
def connect_as(request, mode, fleet):
    if mode == "embedded":
        rosbridge = request.getfixturevalue("rosbridge")

        async def place(who, **credentials):
            del who  # one process: everyone connects to it
            return await rosbridge(**credentials)

    else:
        across = request.getfixturevalue("rosbridge_across_processes")

        async def place(who, **credentials):
            return await across(0 if who == "r1" else 1, **credentials)

    async def connect(who):
        if who in fleet.people:
            return await place(who, user=fleet.people[who])
        return await place(who, token=fleet.tokens[who])

    return connect


async def outcome(connect_as, who, attempt):
    """Run ``attempt(client)`` as ``who``; return its result, or REFUSED at the handshake."""
    try:
        client = await connect_as(who)
    except Refused:
        return REFUSED
    return await attempt(client)


def expect(**allowed):
    return [(who, allowed.get(who, REFUSED)) for who in ALL]


@ACROSS_PROCESSES
@pytest.mark.parametrize(
    ("who", "expected"),
    expect(admin=True, operator=True, viewer=True, foreign_robot=False, peer_robot=True),
)
async def test_subscribing_to_a_robot(connect_as, who, expected):
    robot = await connect_as("r1")

    async def attempt(client):
        await client.send(op="subscribe", topic="/r1/map_id", type="std_msgs/String")
        await client.sync()
        await robot.send(op="publish", topic="map_id", msg={"data": "boccioni_1/Hall"})
        await robot.sync()
        return not await client.quiet()

    assert await outcome(connect_as, who, attempt) == expected


@ACROSS_PROCESSES
@pytest.mark.parametrize(
    ("who", "expected"),
    expect(admin=True, operator=True, viewer=False, foreign_robot=False, peer_robot=False),
)
async def test_sending_a_robot_a_goal(connect_as, who, expected):
    robot = await connect_as("r1")
    await robot.send(op="subscribe", topic="goal")
    await robot.sync()

    async def attempt(client):
        await client.send(op="publish", topic="/r1/goal", msg=GOAL)
        await client.sync()
        return not await robot.quiet()

    assert await outcome(connect_as, who, attempt) == expected


@pytest.mark.parametrize(
    ("who", "expected"),
    expect(admin=False, operator=False, viewer=False, foreign_robot=False, peer_robot=False),
)
async def test_publishing_a_robots_own_data_as_someone_else(connect_as, who, expected):
    robot = await connect_as("r1")
    await robot.send(op="subscribe", topic="map_id")
    await robot.sync()

    async def attempt(client):
        await client.send(op="publish", topic="/r1/map_id", msg={"data": "forged"})
        await client.sync()
        return not await robot.quiet()

    assert await outcome(connect_as, who, attempt) == expected


async def test_a_robot_publishes_inside_its_namespace_only(connect_as):
    robot, other = await connect_as("r1"), await connect_as("peer_robot")
    await other.send(op="subscribe", topic="pose", type="geometry_msgs/PoseStamped")
    await other.sync()
    await robot.send(op="set_level", level="error")
    await robot.send(op="publish", topic="/r2/pose", msg=GOAL)
    assert (await robot.receive())["level"] == "error"
    assert await other.quiet()


async def test_only_admins_publish_shared_topics(connect_as):
    admin, operator = await connect_as("admin"), await connect_as("operator")
    await operator.send(op="subscribe", topic="/announcements", type="std_msgs/String")
    await operator.sync()
    await admin.send(op="publish", topic="/announcements", msg={"data": "hello"})
    assert (await operator.receive())["msg"] == {"data": "hello"}
    await operator.send(op="publish", topic="/announcements", msg={"data": "spam"})
    await operator.sync()
    assert await operator.quiet()


@ACROSS_PROCESSES
@pytest.mark.parametrize(
    ("who", "expected"),
    expect(admin=True, operator=True, viewer=False, foreign_robot=False, peer_robot=False),
)
async def test_calling_a_robots_service(connect_as, who, expected):
    robot = await connect_as("r1")
    await robot.send(op="advertise_service", service="dock", type="std_srvs/Trigger")
    await robot.sync()

    async def attempt(client):
        await client.send(op="call_service", id="c1", service="/r1/dock", args={})
        await client.sync()
        return not await robot.quiet()

    assert await outcome(connect_as, who, attempt) == expected


@pytest.mark.parametrize(
    ("who", "expected"),
    expect(admin=True, operator=False, viewer=False, foreign_robot=False, peer_robot=False),
)
async def test_advertising_a_shared_service(connect_as, who, expected):
    async def attempt(client):
        await client.send(op="advertise_service", service="/shared/echo", type="std_srvs/Trigger")
        response = await client.call("/rosapi/services")
        return "/shared/echo" in response["values"]["services"]

    assert await outcome(connect_as, who, attempt) == expected


@pytest.mark.parametrize("who", ["admin", "peer_robot"])
async def test_nobody_advertises_in_the_servers_namespaces(connect_as, who):
    client = await connect_as(who)
    await client.send(op="advertise_service", service="/rosapi/topics", type="rosapi/Topics")
    await client.send(op="advertise_service", service="cloudnav/route", type="x/Y")
    response = await client.call("/rosapi/topics")
    assert response["result"] is True


@ACROSS_PROCESSES
@pytest.mark.parametrize(
    ("who", "expected"),
    expect(admin=True, operator=True, viewer=False, foreign_robot=False, peer_robot=False),
)
async def test_taking_a_robots_teleop_lock(connect_as, who, expected):
    async def attempt(client):
        response = await client.call("/cloudnav/teleop_lock", {"robot": "r1", "action": "acquire"})
        return response["result"] and response["values"]["success"]

    assert await outcome(connect_as, who, attempt) == expected


@ACROSS_PROCESSES
@pytest.mark.parametrize(
    ("who", "expected"),
    expect(admin=True, operator=True, viewer=True, foreign_robot=False, peer_robot=True),
)
async def test_listing_a_robots_topics(connect_as, who, expected):
    robot = await connect_as("r1")
    await robot.send(op="publish", topic="map_id", msg={"data": "boccioni_1/Hall"})
    await robot.sync()

    async def attempt(client):
        response = await client.call("/rosapi/topics")
        return "/r1/map_id" in response["values"]["topics"]

    assert await outcome(connect_as, who, attempt) == expected


@pytest.mark.parametrize(
    ("who", "expected"),
    expect(admin=True, operator=True, viewer=False, foreign_robot=False, peer_robot=False),
)
async def test_sending_a_goal_to_a_robots_action(connect_as, who, expected):
    robot = await connect_as("r1")
    await robot.send(op="advertise_action", action="navigate", type="nav2_msgs/NavigateToPose")
    await robot.sync()

    async def attempt(client):
        await client.send(
            op="send_action_goal", id="g", action="/r1/navigate", action_type="a/B", args={}
        )
        await client.sync()
        return not await robot.quiet()

    assert await outcome(connect_as, who, attempt) == expected


@pytest.mark.parametrize(
    ("who", "expected"),
    expect(admin=True, operator=True, viewer=False, foreign_robot=False, peer_robot=False),
)
async def test_setting_a_robots_parameter(connect_as, who, expected):
    async def attempt(client):
        response = await client.call("/rosapi/set_param", {"name": "/r1/max_speed", "value": "1"})
        return response["result"]

    assert await outcome(connect_as, who, attempt) == expected


@pytest.mark.parametrize(
    ("who", "expected"),
    expect(admin=False, operator=False, viewer=False, foreign_robot=False, peer_robot=False),
)
async def test_advertising_a_service_in_a_robots_namespace(connect_as, who, expected):
    async def attempt(client):
        await client.send(op="advertise_service", service="/r1/dock", type="std_srvs/Trigger")
        listed = (await client.call("/rosapi/services"))["values"]["services"]
        return "/r1/dock" in listed

    assert await outcome(connect_as, who, attempt) == expected


@ACROSS_PROCESSES
@pytest.mark.parametrize(
    ("who", "expected"),
    expect(admin=True, operator=True, viewer=True, foreign_robot=False, peer_robot=True),
)
async def test_reading_a_robots_latched_map_id(connect_as, who, expected):
    robot = await connect_as("r1")
    await robot.send(op="publish", topic="map_id", msg={"data": "boccioni_1/Hall"})
    await robot.sync()

    async def attempt(client):
        await client.send(op="subscribe", topic="/r1/map_id", type="std_msgs/String")
        return not await client.quiet()

    assert await outcome(connect_as, who, attempt) == expected
