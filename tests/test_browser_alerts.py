"""Alerts on the dashboard, acknowledged by an operator, and the open count on every page;
a lost server connection greys what a page shows live; in a real browser at desktop and
phone sizes."""

from __future__ import annotations

import asyncio
import re
import threading
from collections.abc import Iterator

import pytest
from playwright.sync_api import Browser, BrowserContext, WebSocketRoute, expect

from robots.agent.client import RosbridgeClient
from tests.browser_support import ROBOT, Demo, open_as, screenshot

pytest_plugins = ["tests.browser_support"]
pytestmark = [pytest.mark.browser, pytest.mark.django_db(transaction=True)]

REASON = "no path to the goal: it is inside a wall"


@pytest.fixture(params=[{"width": 1440, "height": 900}, {"width": 390, "height": 844}],
                ids=["desktop", "phone"])  # fmt: skip
def sized(browser: Browser, request: pytest.FixtureRequest) -> Iterator[BrowserContext]:
    opened = browser.new_context(viewport=request.param)
    opened.set_default_timeout(15_000)
    yield opened
    opened.close()


def robot_aborts_a_goal(demo: Demo) -> None:
    """``robot_0`` connects, says its goal was aborted and why, and leaves."""

    async def run() -> None:
        client = RosbridgeClient(demo.server.rosbridge_url(), demo.tokens[ROBOT])
        client.advertise("nav_status", "actionlib_msgs/GoalStatusArray")
        task = asyncio.create_task(client.run())
        await asyncio.wait_for(client.wait_connected(), 10)
        status = {"goal_id": {"id": "g1"}, "status": 4, "text": REASON}
        await client.publish("nav_status", {"header": {"frame_id": ""}, "status_list": [status]})
        await asyncio.sleep(0.5)
        await client.close()
        await task

    thread = threading.Thread(target=asyncio.run, args=(run(),))
    thread.start()
    thread.join(20)


def test_an_operator_sees_an_alert_with_its_reason_and_acknowledges_it(
    sized: BrowserContext, demo: Demo
) -> None:
    page = open_as(sized, demo, "operator", "/")
    expect(page.locator("#alert-count")).to_have_attribute("data-open", "0")
    robot_aborts_a_goal(demo)

    alert = page.locator("#alerts-body tr[data-kind=goal_aborted]")
    expect(alert).to_contain_text(REASON, timeout=15_000)
    expect(page.locator("#alerts-body tr[data-kind=robot_disconnected]")).to_be_visible()
    expect(page.locator("#events-body tr[data-kind=robot_connected]")).to_be_visible()
    expect(page.locator("#alert-count")).to_have_attribute("data-open", "2", timeout=10_000)
    screenshot(page, f"dashboard-alerts-{page.viewport_size['width']}")  # type: ignore[index]

    alert.get_by_role("button", name="Acknowledge").click()
    expect(alert).to_have_count(0)
    expect(page.locator("#alert-count")).to_have_attribute("data-open", "1")
    # Every page shows the count.
    page.goto(demo.url("/buildings/"))
    expect(page.locator("#alert-count")).to_have_text("1 open alert")


def test_a_viewer_sees_alerts_but_acknowledges_none(context: BrowserContext, demo: Demo) -> None:
    robot_aborts_a_goal(demo)
    page = open_as(context, demo, "viewer", "/")
    expect(page.locator("#alerts-body tr[data-kind=goal_aborted]")).to_be_visible()
    expect(page.get_by_role("button", name="Acknowledge")).to_have_count(0)


def test_a_lost_server_greys_the_live_parts_of_the_page(
    context: BrowserContext, demo: Demo
) -> None:
    sockets: list[WebSocketRoute] = []

    def relay(socket: WebSocketRoute) -> None:
        socket.connect_to_server()
        sockets.append(socket)

    context.route_web_socket(re.compile(r"/rosbridge$"), relay)
    page = open_as(context, demo, "operator", "/buildings/boccioni_1/map/")
    expect(page.locator("#conn-state")).to_contain_text("Live")
    sockets[-1].close(code=1006, reason="network lost")
    expect(page.locator("body")).to_have_class(re.compile("server-lost"))
    expect(page.locator("#plan-offline")).to_be_visible()
    screenshot(page, "building-map-server-lost")
    expect(page.locator("#conn-state")).to_contain_text("Live", timeout=15_000)
    expect(page.locator("#plan-offline")).to_be_hidden()
