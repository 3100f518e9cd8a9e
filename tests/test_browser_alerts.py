"""Alerts on the dashboard, acknowledged by an operator, and the open count on every page,
in a real browser at desktop and phone sizes."""

from __future__ import annotations

import asyncio
import threading

import pytest
from playwright.sync_api import BrowserContext, expect

from robots.agent.client import RosbridgeClient
from tests.browser_support import ROBOT, Demo, open_as, screenshot

pytest_plugins = ["tests.browser_support"]
pytestmark = [pytest.mark.browser, pytest.mark.django_db(transaction=True)]

REASON = "no path to the goal: it is inside a wall"


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
