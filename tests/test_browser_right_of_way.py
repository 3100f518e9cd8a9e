"""Right of way on the building's live map (issue 28, points 2 and 5): two robots meet at
Corridor A's entrance door; the map shows who waits, for whom, and where, and who has
the right of way; in a real browser against a live server."""

from __future__ import annotations

import asyncio
import io
import json
import math
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
from django.core.management import call_command
from playwright.sync_api import BrowserContext, expect

from cloudnav_core.messages import path_message, pose_stamped
from robots.agent.client import RosbridgeClient
from tests.browser_support import BUILDING, Demo, open_as, screenshot

pytest_plugins = ["tests.browser_support"]
pytestmark = [pytest.mark.browser, pytest.mark.django_db(transaction=True)]

CORRIDOR = f"{BUILDING}/CorridorA"
# robot_0 in the porch going east through the door; robot_1 in the corridor going west.
ROUTES = {"robot_0": ((2.6, 23.8), (7.0, 23.8)), "robot_1": ((5.5, 23.8), (2.4, 23.8))}


def line(a: tuple[float, float], b: tuple[float, float]) -> list[tuple[float, float]]:
    n = int(math.dist(a, b) / 0.05)
    return [(a[0] + (b[0] - a[0]) * k / n, a[1] + (b[1] - a[1]) * k / n) for k in range(n + 1)]


@pytest.fixture
def meeting(demo: Demo, tmp_path: Path) -> Iterator[None]:
    """Two robots standing either side of the door, each publishing its pose (5 Hz) and
    its plan through the door (once a second)."""
    tokens = tmp_path / "two.json"
    call_command("seed_demo", "--robots", "2", "--tokens-file", str(tokens), stdout=io.StringIO())
    names = json.loads(tokens.read_text())
    url = demo.server.url.replace("http", "ws", 1) + "/rosbridge"
    loop = asyncio.new_event_loop()
    stop = asyncio.Event()
    thread = threading.Thread(
        target=loop.run_until_complete, args=(stand_and_plan(url, names, stop),), daemon=True
    )
    thread.start()
    yield
    loop.call_soon_threadsafe(stop.set)
    thread.join(10)


async def stand_and_plan(url: str, tokens: dict[str, str], stop: asyncio.Event) -> None:
    clients = {name: RosbridgeClient(url, tokens[name]) for name in ROUTES}
    for name, client in clients.items():
        client.advertise(f"/{name}/pose", "geometry_msgs/PoseStamped")
        client.advertise(f"/{name}/plan", "nav_msgs/Path")
    runs = [asyncio.create_task(client.run()) for client in clients.values()]
    started = time.monotonic()
    while not stop.is_set():
        for name, (at, to) in ROUTES.items():
            client = clients[name]
            await client.publish(f"/{name}/pose", pose_stamped(CORRIDOR, (*at, 0.0), time.time()))
            if int((time.monotonic() - started) * 5) % 5 == 0:
                plan = path_message(CORRIDOR, line(at, to), time.time())
                await client.publish(f"/{name}/plan", plan)
        await asyncio.sleep(0.2)
    for client in clients.values():
        await client.close()
    await asyncio.gather(*runs, return_exceptions=True)


def test_the_building_map_shows_who_waits_for_whom_at_the_door(
    meeting: None, demo: Demo, context: BrowserContext
) -> None:
    page = open_as(context, demo, "viewer", f"/buildings/{BUILDING}/map/")
    waiting = page.locator("#robot-list tr[data-robot=robot_1]")
    going = page.locator("#robot-list tr[data-robot=robot_0]")
    expect(waiting).to_have_attribute("data-state", "waits for robot_0", timeout=60_000)
    expect(going).to_have_attribute("data-state", "right of way")
    waiting.click()
    expect(page.locator("#selected-way")).to_contain_text("robot_1 waits at")
    expect(page.locator("#selected-way")).to_contain_text("for robot_0 to pass the narrow place")
    spot = page.evaluate("() => window.cloudnav.floorPlan.robots.get('robot_1').giveWay.spot")
    assert spot["x"] > 3.8  # on robot_1's own side of the door
    page.evaluate("() => window.cloudnav.floorPlan.centerOn(3.7, 23.8)")
    screenshot(page, "building-map-right-of-way")
