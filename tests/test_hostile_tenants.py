"""Tenants stay apart (issue 9, points 3 and 4): what one tenant's people and robots can
do to another tenant's.

REST: a robot shared by two tenants' buildings is renamed, described, rotated and deleted
only by an admin of all its buildings; each admin links and unlinks their own buildings
only, and sees no other tenant's building codes or users, in answers and in the browsable
API's forms; a tag is refused before it is validated.

rosbridge: a name no robot owns lives in one building's realm, so a squatter of another
tenant never reads or commands the robot that later registers that name; grants are
decided again when a robot appears, is renamed, relinked or deleted. Revocation (a token
rotated, a robot deleted, a membership or role removed, a sign-out) closes the sockets and
video streams that depended on it within a second.
"""

from __future__ import annotations

import asyncio
from typing import Any

import pytest
from asgiref.testing import ApplicationCommunicator
from channels.db import database_sync_to_async
from channels.testing import WebsocketCommunicator
from django.contrib.auth.models import User
from django.test import Client

from maps.models import Building
from robots.models import Robot, RobotState
from robots.services import rotate_token
from tests.conftest import client_for, make_building, make_robot, make_submap, make_user
from tests.fixtures_live import RosClient, session_cookie
from tests.support.tenants import CLOSE_WITHIN, closed_soon


@pytest.fixture
def tenants(building: Building, admin: User) -> Any:
    """``boccioni_1`` (admin) and ``theirs_1`` (their_admin, their_user) share robot r1."""
    their_admin = make_user("their_admin", "admin")
    their_user = make_user("their_user", "viewer")
    theirs = make_building(code="theirs_1", name="Theirs", members=[their_admin, their_user])
    make_submap(theirs, code="Secret")
    robot, token = make_robot(name="r1", buildings=[building, theirs])
    return robot, token, theirs


def codes(robot: Robot) -> set[str]:
    return set(robot.buildings.values_list("code", flat=True))


@pytest.mark.parametrize(
    ("method", "path", "body"),
    [
        ("patch", "/api/robots/r1/", {"name": "r9"}),
        ("patch", "/api/robots/r1/", {"description": "mine now"}),
        ("put", "/api/robots/r1/", {"name": "r9", "buildings": ["boccioni_1"]}),
        ("delete", "/api/robots/r1/", None),
        ("post", "/api/robots/r1/rotate_token", None),
    ],
)
def test_an_admin_of_one_building_cannot_change_a_shared_robot_for_all(
    tenants: Any, admin: User, method: str, path: str, body: Any
) -> None:
    robot, _, _ = tenants
    before = Robot.objects.values().get(pk=robot.pk)
    response = getattr(client_for(admin), method)(path, body, format="json")
    assert response.status_code == 403, response.content
    assert Robot.objects.values().get(pk=robot.pk) == before
    assert codes(robot) == {"boccioni_1", "theirs_1"}


def test_an_admin_links_and_unlinks_their_own_buildings_only(
    tenants: Any, admin: User, building: Building
) -> None:
    robot, _, _ = tenants
    make_building(code="mine_2", members=[admin])
    client = client_for(admin)
    answer = client.patch("/api/robots/r1/", {"buildings": ["mine_2"]}, format="json")
    assert answer.status_code == 200
    assert answer.json()["buildings"] == ["mine_2"]
    assert codes(robot) == {"mine_2", "theirs_1"}
    refused = client.patch("/api/robots/r1/", {"buildings": ["theirs_1"]}, format="json")
    assert refused.status_code == 400
    assert codes(robot) == {"mine_2", "theirs_1"}
    assert client.patch("/api/robots/r1/", {"buildings": []}, format="json").status_code == 200
    assert codes(robot) == {"theirs_1"}


def test_an_admin_of_every_building_renames_rotates_and_deletes(tenants: Any, admin: User) -> None:
    _, _, theirs = tenants
    theirs.members.add(admin)
    client = client_for(admin)
    assert client.patch("/api/robots/r1/", {"name": "r9"}, format="json").status_code == 200
    assert client.post("/api/robots/r9/rotate_token").status_code == 200
    assert client.delete("/api/robots/r9/").status_code == 204


def test_a_name_another_tenant_uses_is_refused_as_any_name_no_one_may_have(
    tenants: Any, building: Building, admin: User
) -> None:
    _, _, theirs = tenants
    make_robot(name="secretbot", buildings=[theirs])
    make_robot(name="mine", buildings=[building])
    client = client_for(admin)
    unavailable = {"name": ["This name is not available: choose another."]}
    # another tenant's robot, a namespace the server keeps, one's own robot: one answer
    for name in ("secretbot", "cloudnav", "rosapi", "mine"):
        answer = client.post("/api/robots/", {"name": name, "buildings": ["boccioni_1"]})
        assert (answer.status_code, answer.json()) == (400, unavailable), name
    renamed = client.patch("/api/robots/mine/", {"name": "secretbot"}, format="json")
    assert (renamed.status_code, renamed.json()) == (400, unavailable)
    assert client.patch("/api/robots/mine/", {"name": "mine"}, format="json").status_code == 200
    assert not Robot.objects.filter(name__in=["cloudnav", "rosapi"]).exists()


@pytest.mark.parametrize(
    "path", ["/api/robots/", "/api/robots/r1/", "/api/fleet/", "/api/buildings/"]
)
def test_answers_name_no_other_tenants_building(tenants: Any, admin: User, path: str) -> None:
    response = client_for(admin).get(path, HTTP_ACCEPT="application/json")
    assert response.status_code == 200
    assert "theirs_1" not in response.content.decode()
    assert "their_" not in response.content.decode()


def test_a_robot_sees_no_building_of_another_tenant_in_the_fleet(tenants: Any) -> None:
    other = make_building(code="elsewhere")
    _, token = make_robot(name="r2", buildings=[Building.objects.get(code="boccioni_1"), other])
    body = client_for(token).get("/api/fleet/").content.decode()
    assert "theirs_1" not in body


@pytest.mark.parametrize(
    "path", ["/api/robots/", "/api/robots/r1/", "/api/buildings/", "/api/tags/"]
)
def test_browsable_forms_list_nothing_foreign(tenants: Any, admin: User, path: str) -> None:
    page = client_for(admin).get(path, HTTP_ACCEPT="text/html").content.decode()
    assert "theirs_1" not in page
    assert "their_admin" not in page
    assert "their_user" not in page


def test_an_admin_cannot_add_another_tenants_user_to_their_building(
    tenants: Any, admin: User
) -> None:
    response = client_for(admin).patch(
        "/api/buildings/boccioni_1/", {"members": ["admin", "their_user"]}, format="json"
    )
    assert response.status_code == 400
    assert not Building.objects.get(code="boccioni_1").members.filter(username="their_user")


def test_a_user_of_no_building_yet_can_be_added(tenants: Any, admin: User) -> None:
    make_user("newcomer", "viewer")
    response = client_for(admin).patch(
        "/api/buildings/boccioni_1/", {"members": ["admin", "newcomer"]}, format="json"
    )
    assert response.status_code == 200


@pytest.mark.parametrize(
    "tag",
    [
        {"submap": "Secret", "links_to": "Secret", "marker_id": 3},  # valid there
        {"submap": "Nope", "links_to": "Nope", "marker_id": 10**6},  # invalid there
    ],
)
def test_a_tag_in_another_tenants_building_is_refused_before_it_is_validated(
    tenants: Any, admin: User, tag: dict[str, Any]
) -> None:
    body = {"building": "theirs_1", "x": 1, "y": 1, "yaw": 0, **tag}
    response = client_for(admin).post("/api/tags/", body, format="json")
    assert response.status_code == 404
    assert "Secret" not in response.content.decode()
    assert "marker" not in response.content.decode()


# ---------------------------------------------------------------- rosbridge: squatting and realms

POSE = {"header": {"frame_id": "boccioni_1/Hall"}, "pose": {"position": {"x": 1, "y": 2}}}


@pytest.fixture
def squatter(tenants: Any) -> User:
    """An admin of the other tenant, who may publish any name no robot owns."""
    return User.objects.get(username="their_admin")


@pytest.mark.django_db(transaction=True)
async def test_a_squatter_loses_a_name_when_another_tenant_registers_it(
    rosbridge: Any, squatter: User, building: Building
) -> None:
    spy = await rosbridge(user=squatter)
    for topic, kind in (("/newbot/pose", "geometry_msgs/PoseStamped"), ("/newbot/scan", None)):
        await spy.send(op="subscribe", topic=topic, type=kind or "sensor_msgs/LaserScan")
    await spy.send(op="advertise", topic="/newbot/goal", type="geometry_msgs/PoseStamped")
    planted = await spy.call("/rosapi/set_param", {"name": "/newbot/max_speed", "value": "9"})
    assert planted["result"] is True
    await spy.sync()
    _, token = await database_sync_to_async(make_robot)(name="newbot", buildings=[building])
    robot = await rosbridge(token=token)
    await robot.send(op="subscribe", topic="goal", type="geometry_msgs/PoseStamped")
    await robot.sync()
    await robot.send(op="publish", topic="pose", msg=POSE)
    await robot.sync()
    assert await spy.quiet()  # no pose reaches the squatter
    await spy.send(op="publish", topic="/newbot/goal", msg=POSE)
    await spy.sync()
    assert await robot.quiet()  # and no goal reaches the robot
    answer = await robot.call("/rosapi/get_param", {"name": "max_speed"})
    assert answer["values"]["successful"] is False


@pytest.mark.django_db(transaction=True)
async def test_names_no_robot_owns_are_per_building(
    rosbridge: Any, tenants: Any, admin: User, operator: User
) -> None:
    theirs = await rosbridge(
        user=await database_sync_to_async(User.objects.get)(username="their_user")
    )
    ours = await rosbridge(user=operator)
    for client in (theirs, ours):
        await client.send(op="subscribe", topic="/announcements", type="std_msgs/String")
        await client.sync()
    speaker = await rosbridge(user=admin)
    await speaker.send(op="publish", topic="/announcements", msg={"data": "hello"})
    await speaker.call("/rosapi/set_param", {"name": "/fleet/speed", "value": "1"})
    assert (await ours.receive())["msg"] == {"data": "hello"}
    assert await theirs.quiet()
    listed = (await theirs.call("/rosapi/topics"))["values"]["topics"]
    assert "/announcements" not in listed  # nobody publishes it in their building
    assert not any(name.startswith("/-") for name in listed)
    assert "/announcements" in (await ours.call("/rosapi/topics"))["values"]["topics"]
    value = (await theirs.call("/rosapi/get_param", {"name": "/fleet/speed"}))["values"]
    assert value["successful"] is False
    assert (await ours.call("/rosapi/get_param", {"name": "/fleet/speed"}))["values"][
        "value"
    ] == "1"


@pytest.mark.django_db(transaction=True)
async def test_unlinking_a_robot_withdraws_the_subscriptions_it_granted(
    rosbridge: Any, tenants: Any, operator: User, building: Building
) -> None:
    robot_record, token, _ = tenants
    watcher = await rosbridge(user=operator)
    await watcher.send(op="subscribe", topic="/r1/pose", type="geometry_msgs/PoseStamped")
    await watcher.sync()
    before = await rosbridge(token=token)
    await database_sync_to_async(robot_record.buildings.remove)(building)
    assert await closed_soon(before)  # applied: grants are decided before anything closes
    robot = await rosbridge(token=token)
    await robot.send(op="publish", topic="pose", msg=POSE)
    await robot.sync()
    assert await watcher.quiet()


# ---------------------------------------------------------------- revocation


@pytest.mark.django_db(transaction=True)
@pytest.mark.parametrize("change", ["rotate", "delete", "rename", "unlink"])
async def test_a_robots_connection_closes_when_its_credentials_change(
    rosbridge: Any, building: Building, change: str
) -> None:
    record, token = await database_sync_to_async(make_robot)(name="r1", buildings=[building])
    client = await rosbridge(token=token)
    await client.sync()

    def revoke() -> None:
        if change == "rotate":
            rotate_token(record)
        elif change == "delete":
            record.delete()
        elif change == "rename":
            Robot.objects.filter(pk=record.pk).update(name="r9")
            record.refresh_from_db()
            record.save()
        else:
            record.buildings.remove(building)

    await database_sync_to_async(revoke)()
    assert await closed_soon(client)


@pytest.mark.django_db(transaction=True)
@pytest.mark.parametrize("change", ["membership", "role", "logout", "deleted"])
async def test_a_persons_connection_closes_when_their_access_is_revoked(
    rosbridge: Any, building: Building, operator: User, change: str
) -> None:
    cookie = await database_sync_to_async(session_cookie)(operator)
    client = await rosbridge_with_cookie(cookie)
    await client.sync()

    def revoke() -> None:
        if change == "membership":
            building.members.remove(operator)
        elif change == "role":
            operator.groups.clear()
        elif change == "deleted":
            operator.delete()
        else:
            browser = Client()
            browser.cookies["sessionid"] = cookie.decode().split("=", 1)[1]
            assert browser.post("/accounts/logout/").status_code in (200, 302)

    await database_sync_to_async(revoke)()
    assert await closed_soon(client)


@pytest.mark.django_db(transaction=True)
async def test_another_session_of_the_same_person_stays_open_after_a_logout(
    rosbridge: Any, building: Building, operator: User
) -> None:
    other = await rosbridge(user=operator)
    cookie = await database_sync_to_async(session_cookie)(operator)
    client = await rosbridge_with_cookie(cookie)

    def logout() -> None:
        browser = Client()
        browser.cookies["sessionid"] = cookie.decode().split("=", 1)[1]
        browser.post("/accounts/logout/")

    await database_sync_to_async(logout)()
    assert await closed_soon(client)
    assert await other.communicator.receive_nothing(0.3)
    await other.sync()


async def rosbridge_with_cookie(cookie: bytes) -> Any:
    from cloudnav_web.asgi import application

    headers = [(b"host", b"testserver"), (b"cookie", cookie), (b"origin", b"http://testserver")]
    communicator = WebsocketCommunicator(application, "/rosbridge", headers=headers)
    connected, _ = await communicator.connect(timeout=3)
    assert connected
    return RosClient(communicator)


@pytest.mark.django_db(transaction=True)
async def test_a_deleted_robot_that_stays_connected_blocks_no_fleet_state(
    rosbridge: Any, building: Building, settings: Any
) -> None:
    settings.CLOUDNAV_FLEET_FLUSH_INTERVAL = 0.05
    doomed, doomed_token = await database_sync_to_async(make_robot)(name="r1", buildings=[building])
    _, token = await database_sync_to_async(make_robot)(name="r2", buildings=[building])
    gone, other = await rosbridge(token=doomed_token), await rosbridge(token=token)
    await gone.send(op="publish", topic="map_id", msg={"data": "boccioni_1/Hall"})
    await gone.sync()
    await database_sync_to_async(doomed.delete)()
    await gone.send(op="publish", topic="map_id", msg={"data": "boccioni_1/Atrium"})
    await other.send(op="publish", topic="map_id", msg={"data": "boccioni_1/CorridorA"})
    deadline = asyncio.get_running_loop().time() + 3

    def written() -> bool:
        state = RobotState.objects.filter(robot__name="r2").first()
        return state is not None and state.map_id == "boccioni_1/CorridorA"

    while not await database_sync_to_async(written)():
        assert asyncio.get_running_loop().time() < deadline
        await asyncio.sleep(0.05)


# ---------------------------------------------------------------- video streams


async def open_stream(query: dict[str, str], headers: dict[str, str]) -> ApplicationCommunicator:
    from cloudnav_web.asgi import application
    from tests.support.http_scopes import http_scope

    app = ApplicationCommunicator(application, http_scope("/stream", query, headers))
    await app.send_input({"type": "http.request", "body": b"", "more_body": False})
    start = await app.receive_output(3)
    assert start["status"] == 200
    return app


async def stream_ends(app: ApplicationCommunicator, wait: float = CLOSE_WITHIN) -> bool:
    loop = asyncio.get_running_loop()
    deadline = loop.time() + wait
    while True:
        try:
            message = await app.receive_output(max(0.01, deadline - loop.time()))
        except TimeoutError:
            return False
        if not message.get("more_body", False):
            return True


async def still_streaming(app: ApplicationCommunicator, wait: float = 0.3) -> bool:
    """True if ``app``'s body has not ended within ``wait`` (what it sent is read)."""
    while not await app.receive_nothing(wait):
        if not (await app.receive_output(1)).get("more_body", False):
            return False
    return True


@pytest.mark.django_db(transaction=True)
@pytest.mark.parametrize("kind", ["mjpeg", "vp8"])
@pytest.mark.parametrize("change", ["rotate", "delete"])
async def test_a_robots_video_stream_ends_when_its_token_is_revoked(
    rosbridge: Any, building: Building, kind: str, change: str
) -> None:
    record, token = await database_sync_to_async(make_robot)(name="r1", buildings=[building])
    await rosbridge(token=token)  # starts this process's hub
    query = {"topic": "/r1/camera/image/compressed", "type": kind, "token": token}
    app = await open_stream(query, {})
    revoke = rotate_token if change == "rotate" else Robot.delete
    await database_sync_to_async(revoke)(record)
    assert await stream_ends(app)
    await app.send_input({"type": "http.disconnect"})


@pytest.mark.django_db(transaction=True)
@pytest.mark.parametrize("kind", ["mjpeg", "vp8"])
async def test_a_persons_video_stream_ends_when_they_leave_the_building(
    rosbridge: Any, building: Building, viewer: User, kind: str
) -> None:
    _, token = await database_sync_to_async(make_robot)(name="r1", buildings=[building])
    await rosbridge(token=token)
    cookie = (await database_sync_to_async(session_cookie)(viewer)).decode()
    query = {"topic": "/r1/camera/image/compressed", "type": kind}
    app = await open_stream(query, {"Cookie": cookie})
    kept = await open_stream({**query, "token": token}, {})
    await database_sync_to_async(building.members.remove)(viewer)
    assert await stream_ends(app)
    assert await still_streaming(kept)
    for stream in (app, kept):
        await stream.send_input({"type": "http.disconnect"})


# ---------------------------------------------------------------- scaled mode

CHANGE = """
import django
django.setup()
from django.contrib.auth.models import User
from maps.models import Building
from robots.models import Robot
from robots.services import rotate_token
rotate_token(Robot.objects.get(name="r1"))
Building.objects.get(code="boccioni_1").members.remove(User.objects.get(username="operator"))
"""


def change_elsewhere(database_url: str) -> None:
    """Rotate r1's token and remove ``operator`` from the building in a process of its
    own, as an admin's command would, announcing over the shared Redis."""
    import os
    import subprocess
    import sys

    from tests.fixtures_live import BASE_DIR, scaled_redis_url

    env = {
        **os.environ,
        "DJANGO_SETTINGS_MODULE": "cloudnav_web.settings_test",
        "DATABASE_URL": database_url,
        "CLOUDNAV_LIVE_SERVER": "1",
        "REDIS_URL": scaled_redis_url(),
    }
    done = subprocess.run(
        [sys.executable, "-c", CHANGE], cwd=BASE_DIR, env=env, capture_output=True, timeout=60
    )
    assert done.returncode == 0, done.stderr
    assert b"could not announce" not in done.stderr, done.stderr


@pytest.mark.scaled
async def test_in_scaled_mode_revocation_closes_connections_on_every_process(
    scaled_servers: Any,
) -> None:
    import time

    import websockets

    cluster = scaled_servers(2)
    robot_server, person_server = cluster.servers
    robot = await websockets.connect(robot_server.rosbridge_url(cluster.tokens["r1"]))
    person = await websockets.connect(
        person_server.rosbridge_url(),
        additional_headers={"Cookie": cluster.cookies["operator"], "Origin": person_server.url},
    )
    bystander = await websockets.connect(robot_server.rosbridge_url(cluster.tokens["r2"]))
    await asyncio.to_thread(change_elsewhere, cluster.database_url)
    started = time.monotonic()
    for socket in (robot, person):
        await asyncio.wait_for(socket.wait_closed(), CLOSE_WITHIN)
    assert time.monotonic() - started < CLOSE_WITHIN
    await bystander.send('{"op": "call_service", "id": "t", "service": "/rosapi/get_time"}')
    assert '"t"' in await asyncio.wait_for(bystander.recv(), 3)
    await bystander.close()


# ---------------------------------------------------------------- realms and withdrawal, as units


def test_a_realm_is_a_segment_no_client_can_write() -> None:
    from telemetry.domain import names
    from telemetry.exceptions import InvalidName

    inside = names.in_realm(names.building_realm(3), "/announcements")
    assert inside == "/-b3/announcements"
    assert names.realm_of(inside) == "-b3"
    assert names.outside_realm(inside) == "/announcements"
    assert names.realm_of("/r1/pose") is None
    assert names.without_realms(f"Service {inside} does not exist") == (
        "Service /announcements does not exist"
    )
    with pytest.raises(InvalidName):
        names.absolute(inside)
    assert names.topic_channel(inside) != names.topic_channel("/announcements")


def test_the_bus_withdraws_one_subscription_or_publication() -> None:
    from telemetry.domain.bus import SubscribeParams, TopicBus

    class Timer:
        def cancel(self) -> None:
            pass

    class Peer:
        key = "p"

        def __init__(self) -> None:
            self.got: list[Any] = []

        def deliver(self, wire: Any) -> None:
            self.got.append(wire)

    bus, peer = TopicBus(scheduler=lambda _delay, _callback: Timer()), Peer()
    bus.subscribe(peer, "/a", "std_msgs/String", SubscribeParams(), "s1", spelling="a")
    bus.advertise(peer, "/b", "std_msgs/String")
    assert sorted(bus.holdings(peer), key=str) == [("/a", "a"), ("/b", None)]
    bus.withdraw(peer, "/a", "a")
    bus.withdraw(peer, "/b", None)
    assert bus.holdings(peer) == []
    assert bus.get("/a") is None
    assert bus.get("/b") is None
