"""What goes wrong out there reaches the dashboard: a robot that stands still with a goal
(stuck), one that stops talking while connected (silent), and an operator's page that
stalls while driving a real simulated robot (the dead-man stop, then the teleop lock
lapsing); in a real browser against a live server, at desktop and phone sizes."""

from __future__ import annotations

import json
import re
import threading
import time
from pathlib import Path
from typing import Any

import pytest
from playwright.sync_api import BrowserContext, Page, WebSocketRoute, expect

from telemetry.domain.events import STUCK_AFTER_S
from tests.browser_support import ROBOT, SIZES, Demo, open_as, screenshot, speaking_robot

pytest_plugins = ["tests.browser_support"]
pytestmark = [pytest.mark.browser, pytest.mark.django_db(transaction=True)]

DESKTOP: Any = SIZES[0]
# The teleop lock's time to live after the last command
# (telemetry.rosbridge.teleop_locks.TeleopLocks).
LOCK_TTL_S = 5.0


def dashboard(context: BrowserContext, demo: Demo) -> Page:
    page = open_as(context, demo, "operator", "/")
    expect(page.locator("#conn-state")).to_contain_text("Live")
    return page


def test_a_robot_stuck_with_a_goal_then_silent_raises_both_alerts(
    sized: BrowserContext, demo: Demo
) -> None:
    speaking = threading.Event()
    speaking.set()
    with speaking_robot(demo, speaking, goal_active=True):
        page = dashboard(sized, demo)
        stuck = page.locator("#alerts-body tr[data-kind=robot_stuck]")
        expect(stuck).to_contain_text(ROBOT, timeout=int((STUCK_AFTER_S + 20) * 1000))
        speaking.clear()
        silent = page.locator("#alerts-body tr[data-kind=robot_silent]")
        expect(silent).to_contain_text(ROBOT, timeout=20_000)
        expect(page.locator("#alert-count")).to_have_attribute("data-open", "2")
        screenshot(page, f"dashboard-stuck-silent-{page.viewport_size['width']}")  # type: ignore[index]


class StallingSocket:
    """Relays a page's rosbridge connection, and can stall what the page sends, as a
    network that holds frames back: while ``stalled`` they wait; ``resume`` delivers the
    waiting commands (``publish`` frames; the rest, lock renewals among them, are lost)
    and forwards again."""

    def __init__(self) -> None:
        self.stalled = False
        self.waiting: list[str | bytes] = []
        self.server: WebSocketRoute | None = None

    def route(self, socket: WebSocketRoute) -> None:
        server = self.server = socket.connect_to_server()

        def to_server(message: str | bytes) -> None:
            if self.stalled:
                self.waiting.append(message)
            else:
                server.send(message)

        socket.on_message(to_server)

    def resume(self) -> None:
        assert self.server is not None
        for message in self.waiting:
            if publishes(message):
                self.server.send(message)
        self.waiting = []
        self.stalled = False


def publishes(message: str | bytes) -> bool:
    try:
        frame: Any = json.loads(message)
    except ValueError:
        return False
    return isinstance(frame, dict) and frame.get("op") == "publish"


def test_a_stalled_operator_page_stops_the_robot_and_its_lock_lapses(
    sized: BrowserContext, demo: Demo, agent: Path
) -> None:
    watcher = dashboard(sized, demo)
    # The driver in a window of its own: a page in the watcher's would be a background tab.
    driving = sized.browser.new_context(viewport=DESKTOP)  # type: ignore[union-attr]
    link = StallingSocket()
    driving.route_web_socket(re.compile(r"/rosbridge$"), link.route)
    driver = open_as(driving, demo, "operator", f"/robots/{ROBOT}/")
    expect(driver.locator("#robot-online")).to_have_text("online", timeout=30_000)
    driver.click("#lock-acquire")
    expect(driver.locator("#lock-state")).to_have_text("You are driving")
    # Held forward on the joystick (a key held down would be let go when the window blurs).
    pad = driver.locator("#joystick").bounding_box()
    assert pad is not None
    centre = (pad["x"] + pad["width"] / 2, pad["y"] + pad["height"] / 2)
    driver.mouse.move(*centre)
    driver.mouse.down()
    driver.mouse.move(centre[0], centre[1] - pad["height"] / 3, steps=4)
    expect(driver.locator("#odom-speed")).not_to_have_text("0.00 m/s", timeout=15_000)

    # The page goes quiet while driving: the server stops the robot after 0.5 s...
    link.stalled = True
    stalled_at = time.monotonic()
    events = watcher.locator("#events-body")
    expect(events.locator("tr[data-kind=deadman_stop]")).to_contain_text(ROBOT, timeout=15_000)
    # ...and the page's commands, delivered once its lock's 5 s are over (the lock lapses a
    # set time after the last command: only time tells), find it lapsed.
    watcher.wait_for_timeout(max(0.0, stalled_at + LOCK_TTL_S + 1.5 - time.monotonic()) * 1000)
    link.resume()
    expect(events.locator("tr[data-kind=teleop_lapsed]")).to_contain_text(ROBOT, timeout=15_000)
    driver.mouse.up()
    screenshot(watcher, f"dashboard-deadman-lapsed-{watcher.viewport_size['width']}")  # type: ignore[index]
    driving.close()
