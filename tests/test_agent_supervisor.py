"""The Maps Supervisor's bundles and routes against the real server: conditional requests
(seen in daphne's access log), held maps when the server is away, edits downloaded
again, and routes that agree with the server's route endpoint."""

from __future__ import annotations

import itertools
import math
import re

import httpx
import numpy as np
import pytest

from cloudnav_core.params import RobotConfig
from maps.domain.demo_building import PAPER_ROUTE, demo_building
from maps.domain.topology import approach_pose
from maps.models import EnvironmentalTag
from robots.agent.robot import PoseTracker, Robot
from robots.agent.sim.hardware import SimHardware
from robots.agent.sim.world import demo_world
from robots.agent.supervisor.bundle_cache import BundleCache
from robots.agent.supervisor.legs import Destination, LegKind
from robots.agent.supervisor.maps_supervisor import IN_WALL_S, MapsSupervisor
from robots.agent.supervisor.submaps import BundleError, submap_from_bundle
from robots.agent.whereabouts import Localisation
from tests.conftest import make_robot
from tests.fixtures_live import ACCESS_LOG_ALL, LiveServer, LiveServers

pytestmark = pytest.mark.django_db(transaction=True)

CORRIDOR_A = "boccioni_1/CorridorA"
BUNDLE_LINE = re.compile(r'"GET /api/buildings/boccioni_1/maps/(\w+)/bundle" (\d{3})')


@pytest.fixture
def daphne_server(daphne_servers: LiveServers) -> LiveServer:
    """The live server, its access log with the unchanged bundle checks (304) these tests
    count."""
    return daphne_servers.start(env=ACCESS_LOG_ALL)


def over_the_network(server: LiveServer, token: str) -> httpx.AsyncClient:
    return httpx.AsyncClient(base_url=server.url, headers={"Authorization": f"Token {token}"})


async def test_a_held_map_is_asked_for_conditionally_and_never_downloaded_again(
    daphne_server: LiveServer, demo_token: str
):
    async with over_the_network(daphne_server, demo_token) as http:
        cache = BundleCache(http)
        first = await cache.load(CORRIDOR_A)
        again = await cache.load(CORRIDOR_A)
    assert again is first
    assert (cache.downloads, cache.revalidated) == (1, 1)
    # The server saw one download and one conditional request answered 304, no body.
    assert BUNDLE_LINE.findall(daphne_server.log()) == [("CorridorA", "200"), ("CorridorA", "304")]


async def test_a_held_map_is_used_while_the_server_is_away(daphne_server: LiveServer, demo_token):
    async with over_the_network(daphne_server, demo_token) as http:
        cache = BundleCache(http)
        held = await cache.load(CORRIDOR_A)
        daphne_server.stop()
        assert await cache.load(CORRIDOR_A) is held
        with pytest.raises(BundleError):
            await cache.load("boccioni_1/Atrium1")  # never held: nothing to fall back on


async def test_an_edited_map_is_downloaded_again(cloud):
    cache = BundleCache(cloud)
    before = await cache.load(CORRIDOR_A)
    await EnvironmentalTag.objects.filter(marker_id=1).aupdate(x=17.7)
    after = await cache.load(CORRIDOR_A)
    assert cache.downloads == 2
    assert after.etag != before.etag
    assert after.tags[1].x == 17.7


async def test_a_map_of_a_building_it_may_not_use_is_refused(cloud):
    from asgiref.sync import sync_to_async

    robot_token = (await sync_to_async(make_robot)(name="stranger"))[1]  # in no building
    cloud.headers["Authorization"] = f"Token {robot_token}"
    with pytest.raises(BundleError, match="HTTP 40"):
        await BundleCache(cloud).load(CORRIDOR_A)


def test_a_bundle_it_cannot_read_is_an_error():
    with pytest.raises(BundleError):
        submap_from_bundle({"map": "CorridorA", "image": {"name": "a.pgm", "data": "!"}}, "")
    with pytest.raises(BundleError):
        submap_from_bundle({"yaml": "image: a.pgm\n", "image": {"name": "a.pgm", "data": ""}}, "")


async def test_its_routes_agree_with_the_servers_route_endpoint(cloud):
    cache = BundleCache(cloud)
    codes = [submap.code for submap in demo_building().submaps]
    for code in codes:  # holding every bundle, it knows every tag leading on
        await cache.load(f"boccioni_1/{code}")
    supervisor = MapsSupervisor(cache, PoseTracker())
    for start, goal in itertools.permutations(codes, 2):
        supervisor.current = cache.held[f"boccioni_1/{start}"]
        ours = [(step.submap, step.tag and step.tag.marker_id) for step in supervisor.route(goal)]
        answer = await cloud.get(
            "/api/buildings/boccioni_1/route", params={"from": start, "to": goal}
        )
        theirs = [(s["map"], s["tag"] and s["tag"]["marker_id"]) for s in answer.json()["steps"]]
        assert ours == theirs, (start, goal)


async def test_it_never_routes_along_an_edge_no_tag_lets_it_cross(cloud):
    # An admin joins Corridor A straight to Office 7, cheaply, with no tag at either end.
    from asgiref.sync import sync_to_async

    from maps import services
    from maps.domain.topology import Edge
    from maps.models import Building

    demo = demo_building()
    building = await Building.objects.aget(code="boccioni_1")
    edges = [Edge(e.a, e.b, e.cost) for e in demo.edges] + [Edge("CorridorA", "Office7", 1.0)]
    await sync_to_async(services.replace_topology)(building, {}, edges)
    cache = BundleCache(cloud)
    supervisor = MapsSupervisor(cache, PoseTracker())
    supervisor.current = await cache.load(CORRIDOR_A)  # the only bundle it holds
    route = [step.submap for step in supervisor.route("Office7")]
    assert route == list(PAPER_ROUTE)
    answer = await cloud.get(
        "/api/buildings/boccioni_1/route", params={"from": "CorridorA", "to": "Office7"}
    )
    assert [s["map"] for s in answer.json()["steps"]] == route


async def test_a_tag_that_does_not_lead_on_is_read_but_not_entered(cloud):
    # Before Room A's door in Corridor C, heading for Atrium 2: the robot reads the tag
    # (it resets its pose from it) but stays in Corridor C and fetches nothing more.
    room_a_tag = next(t for t in demo_building().tags if t.links_to == "RoomA")
    pose = approach_pose((room_a_tag.x, room_a_tag.y, room_a_tag.yaw))
    hardware = SimHardware(demo_world(), pose, seed=5)
    tracker = PoseTracker()
    cache = BundleCache(cloud)
    supervisor = MapsSupervisor(cache, tracker)
    robot = Robot(hardware, supervisor, tracker, _Silent(), RobotConfig(camera_rate=0))
    supervisor.make_current(await cache.load("boccioni_1/CorridorC"))
    supervisor.set_destination(Destination("boccioni_1", "Atrium2", (40.0, 7.0, 0.0)))
    tracker.reset((pose[0] + 0.3, pose[1] - 0.2, pose[2] + 0.1), _tiny(), tracker.odom)
    for _ in range(4):
        await robot.tick()
        await robot.settle()
    assert any(d.payload and d.payload.map_code == "RoomA" for d in robot.detections)
    assert supervisor.current is not None
    assert supervisor.current.code == "CorridorC"
    assert list(cache.held) == ["boccioni_1/CorridorC"]
    # Reset from the tag it read: the drift given above is gone.
    assert math.dist(tracker.pose()[:2], pose[:2]) < 0.05


async def test_a_pose_estimate_inside_a_wall_makes_the_robot_lost_and_look_for_a_tag(cloud):
    # In the middle of Corridor A, no tag near: the estimate is moved behind the south
    # wall (where one went in a crowd at tag 1). It stays placed for IN_WALL_S, then it
    # is lost and, given a goal, turns looking for a tag instead of planning from a wall.
    truth = (10.0, 23.0, 0.0)
    hardware = SimHardware(demo_world(), truth, seed=5)
    tracker = PoseTracker()
    cache = BundleCache(cloud)
    supervisor = MapsSupervisor(cache, tracker)
    robot = Robot(hardware, supervisor, tracker, _Silent(), RobotConfig(camera_rate=0))
    supervisor.make_current(await cache.load(CORRIDOR_A))
    tracker.reset(truth, _tiny(), tracker.odom)
    for _ in range(round(2 * IN_WALL_S / robot.config.period)):
        await robot.tick()  # where it truly is: placed all along
    assert supervisor.whereabouts().state is Localisation.LOCALISED
    tracker.reset((17.259, 21.691, 0.0), _tiny(), tracker.odom)
    started = robot.seconds
    while robot.seconds - started < IN_WALL_S - 0.5:
        await robot.tick()
        assert supervisor.current is not None
    while supervisor.current is not None:
        assert robot.seconds - started < IN_WALL_S + 0.5, "never lost"
        await robot.tick()
    assert supervisor.whereabouts().state is Localisation.LOST
    supervisor.set_destination(Destination("boccioni_1", "Atrium1", (20.0, 23.2, 0.0)))
    leg = supervisor.leg(tracker.pose(), tracker.odom, robot.seconds)
    assert leg.kind is LegKind.SEARCH


async def test_a_lost_robot_reading_a_tag_of_a_map_it_never_held_is_placed_by_it(cloud):
    # Lost in Room B before tag 19 (it leads to Atrium 2, whose bundle holds only its own
    # tags): the crossings in Atrium 2's bundle say the tag stands in Room B, whose bundle
    # is fetched too, so the tag places the robot instead of being passed over.
    tag_19 = next(t for t in demo_building().tags if t.marker_id == 19)
    truth = approach_pose((tag_19.x, tag_19.y, tag_19.yaw))
    hardware = SimHardware(demo_world(), truth, seed=5)
    tracker = PoseTracker()
    cache = BundleCache(cloud)
    supervisor = MapsSupervisor(cache, tracker)
    robot = Robot(hardware, supervisor, tracker, _Silent(), RobotConfig(camera_rate=0))
    for _ in range(10):
        await robot.tick()
        await robot.settle()
        if supervisor.current is not None:
            break
    assert supervisor.current is not None
    assert supervisor.current.map_id == "boccioni_1/Atrium2"
    assert supervisor.placed_by == "tag 19"
    assert set(cache.held) == {"boccioni_1/Atrium2", "boccioni_1/RoomB"}
    assert math.dist(tracker.pose()[:2], truth[:2]) < 0.1


class _Silent:
    async def publish(self, _topic: str, _msg: dict) -> bool:
        return True


def _tiny() -> np.ndarray:
    return np.diag([1e-4, 1e-4, 1e-4])
