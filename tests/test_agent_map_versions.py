"""A robot driving in a sub-map takes a new version of it without a restart: its
conditional request answers 200 with the new bundle, the map is swapped under the pose
estimate, and ``map_id`` says the version held."""

from __future__ import annotations

from typing import Any

import pytest
from asgiref.sync import sync_to_async

from cloudnav_core.params import RobotConfig
from maps import versions
from maps.domain.demo_building import demo_building
from maps.models import SubMap
from robots.agent.robot import PoseTracker, Robot
from robots.agent.sim.hardware import SimHardware
from robots.agent.sim.world import demo_world
from robots.agent.supervisor.bundle_cache import BundleCache
from robots.agent.supervisor.maps_supervisor import MapsSupervisor

pytestmark = pytest.mark.django_db(transaction=True)


class Recorder:
    def __init__(self) -> None:
        self.sent: list[tuple[str, Any]] = []

    async def publish(self, topic: str, msg: Any) -> bool:
        self.sent.append((topic, msg))
        return True

    def said(self, topic: str) -> list[Any]:
        return [msg["data"] for name, msg in self.sent if name == topic]


def roll_back_corridor_a() -> None:
    submap = SubMap.objects.get(code="CorridorA")
    versions.rollback(submap, 1, note="a new version while robots drive")


async def test_a_robot_in_the_sub_map_takes_the_new_version_while_it_drives(cloud):
    start = demo_building().robot_starts[0]
    tracker = PoseTracker()
    cache = BundleCache(cloud)
    supervisor = MapsSupervisor(cache, tracker)
    recorder = Recorder()
    config = RobotConfig(camera_rate=0, detect_rate=0, map_check_rate=10.0)
    robot = Robot(SimHardware(demo_world(), start, seed=3), supervisor, tracker, recorder, config)
    supervisor.make_current(await cache.load("boccioni_1/CorridorA"), "test")
    held = supervisor.current
    assert held is not None
    assert held.revision == 1
    await robot.tick()
    await robot.settle()
    assert recorder.said("map_id") == ["boccioni_1/CorridorA@v1"]

    await sync_to_async(roll_back_corridor_a)()
    for _ in range(3):
        await robot.tick()
        await robot.settle()

    now = supervisor.current
    assert now is not held
    assert now is not None
    assert now.revision == 2
    assert recorder.said("map_id")[-1] == "boccioni_1/CorridorA@v2"
    assert supervisor.placed_by == "test"  # still where it was: the frame is the same
    assert cache.downloads == 2
    assert cache.revalidated >= 1


async def test_an_unchanged_map_is_only_revalidated(cloud):
    tracker = PoseTracker()
    cache = BundleCache(cloud)
    supervisor = MapsSupervisor(cache, tracker)
    supervisor.make_current(await cache.load("boccioni_1/CorridorA"))
    assert await supervisor.refresh() is False
    assert (cache.downloads, cache.revalidated) == (1, 1)
