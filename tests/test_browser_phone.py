"""Every page at a phone's width (390 x 844): nothing wider than the screen, STOP always
within reach on a robot's page, and the map zooms with two fingers."""

from __future__ import annotations

import json
import re
import time
from collections.abc import Callable

import pytest
from playwright.sync_api import BrowserContext, Page, expect

from tests.browser_support import BUILDING, PHONE, ROBOT, Demo, pinch, screenshot

pytest_plugins = ["tests.browser_support"]
pytestmark = [pytest.mark.browser, pytest.mark.django_db(transaction=True)]

PAGES = [
    ("operator", "/"),
    ("operator", "/buildings/"),
    ("operator", f"/buildings/{BUILDING}/"),
    ("operator", f"/buildings/{BUILDING}/map/"),
    ("operator", f"/buildings/{BUILDING}/maps/CorridorA/"),
    ("operator", f"/robots/{ROBOT}/"),
    ("admin", "/robots/"),
    ("admin", f"/buildings/{BUILDING}/upload/"),
]


def open_as(context: BrowserContext, demo: Demo, username: str, path: str) -> Page:
    """As ``browser_support.open_as``, but ready once the document is: a robot page with no
    robot keeps loading its camera stream."""
    name, value = demo.cookies[username]
    context.add_cookies([{"name": name, "value": value, "url": demo.server.url}])
    page = context.new_page()
    page.goto(demo.url(path), wait_until="domcontentloaded")
    return page


def test_no_page_is_wider_than_a_phone(phone: BrowserContext, demo: Demo) -> None:
    wide = {}
    for user, path in PAGES:
        page = open_as(phone, demo, user, path)
        page.wait_for_timeout(1500)  # the page's script fills it in
        width = page.evaluate("document.documentElement.scrollWidth")
        if width > PHONE["width"]:
            wide[path] = width
        screenshot(page, "phone" + path.replace("/", "-").rstrip("-"))
        page.close()
    assert wide == {}


def test_stop_is_always_within_reach_and_the_map_pinch_zooms(
    phone: BrowserContext, demo: Demo
) -> None:
    page = open_as(phone, demo, "operator", f"/robots/{ROBOT}/")
    stop = page.locator("#stop-button")
    expect(stop).to_be_in_viewport()
    page.evaluate("window.scrollTo(0, document.body.scrollHeight)")
    expect(stop).to_be_in_viewport()
    page.evaluate("window.scrollTo(0, 0)")
    before = page.evaluate("window.cloudnav.robotPage.view.view.scale")
    pinch(page, "#map-canvas")
    after = page.evaluate("window.cloudnav.robotPage.view.view.scale")
    assert after > 2 * before


def test_the_touch_joystick_drives_once_the_operator_holds_control(
    phone: BrowserContext, demo: Demo
) -> None:
    page = open_as(phone, demo, "operator", f"/robots/{ROBOT}/")
    sent: list[str] = []
    page.on("websocket", lambda ws: ws.on("framesent", lambda frame: sent.append(str(frame))))
    page.reload(wait_until="domcontentloaded")
    expect(page.locator("#conn-state")).to_contain_text("Live")
    page.click("#lock-acquire")
    expect(page.locator("#lock-state")).to_have_text("You are driving")
    pad = page.locator("#joystick")
    pad.scroll_into_view_if_needed()
    box = pad.bounding_box()
    assert box is not None
    cx, cy = box["x"] + box["width"] / 2, box["y"] + box["height"] / 2
    cdp = page.context.new_cdp_session(page)
    start = {"x": cx, "y": cy, "id": 1}
    cdp.send("Input.dispatchTouchEvent", {"type": "touchStart", "touchPoints": [start]})
    for step in range(1, 6):
        point = {"x": cx, "y": cy - step * box["height"] / 10, "id": 1}
        cdp.send("Input.dispatchTouchEvent", {"type": "touchMove", "touchPoints": [point]})
        page.wait_for_timeout(50)  # a finger moves over frames
    page.wait_for_function("window.cloudnav.robotPage.teleop.stick.y < -0.8")
    stick = page.evaluate("window.cloudnav.robotPage.teleop.stick")
    assert stick["y"] < -0.8  # pushed forward (up the screen)
    assert abs(stick["x"]) < 0.2
    # nipplejs draws the stick where the finger is, and the page drives forward with it.
    expect(page.locator("#joystick .front")).to_have_attribute(
        "style", re.compile(r"translate\(-?\d+(\.\d+)?px, ?-\d+")
    )
    screenshot(page, "robot-phone-joystick")
    page.wait_for_function("window.cloudnav.robotPage.teleop.command()[0] > 0")
    wait_for(page, lambda: any(forward_command(frame) for frame in sent), "a forward cmd_vel")
    cdp.send("Input.dispatchTouchEvent", {"type": "touchEnd", "touchPoints": []})
    expect(page.locator("#stop-button")).to_be_in_viewport()
    page.wait_for_function("window.cloudnav.robotPage.teleop.stick.y === 0")


def forward_command(frame: str) -> bool:
    """Whether ``frame`` publishes a cmd_vel that drives forward."""
    try:
        message = json.loads(frame)
    except ValueError:
        return False
    if message.get("op") != "publish" or not message.get("topic", "").endswith("/cmd_vel"):
        return False
    return float(message["msg"]["linear"]["x"]) > 0


def wait_for(page: Page, condition: Callable[[], bool], what: str, seconds: float = 10.0) -> None:
    """Wait until ``condition()``; Playwright delivers the page's events meanwhile."""
    deadline = time.monotonic() + seconds
    while not condition():
        if time.monotonic() > deadline:
            raise AssertionError(f"no {what} within {seconds} s")
        page.wait_for_timeout(100)
