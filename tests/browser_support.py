"""Fixtures of the browser tests (``test_browser_*.py`` load them with ``pytest_plugins``).

A real Chromium (Debian's, at ``/usr/bin/chromium``) driven by Playwright for Python,
against a live daphne server (``tests.fixtures_live``) on the test database, with the demo
building seeded and, where a test needs one, a simulated robot: ``python -m robots.agent``
in its own process. Screenshots go to ``test-artifacts/screenshots/``.

Playwright's sync API keeps an event loop running in the test's thread, where Django then
refuses ORM calls; so the browser starts after the database work (seeding, sessions) is
done and closes before the test database is flushed, and test bodies read the server's
state through its API, not the ORM. (No asserts here: PYTEST_DONT_REWRITE.)
"""

from __future__ import annotations

import asyncio
import io
import json
import math
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest
from django.contrib.auth.models import User
from django.core.management import call_command
from playwright.sync_api import Browser, BrowserContext, Page, expect, sync_playwright

from maps.domain.demo_building import demo_building
from robots.agent.client import RosbridgeClient
from tests.fixtures_live import BASE_DIR, LiveServer, agent_process, session_cookie

ACTION_TIMEOUT_MS = 30_000
"""How long a page action or wait may take: the pages answer in well under a second,
but a live server, robots and browsers sharing two cores with other tests can stall."""
EXPECT_TIMEOUT_MS = 15_000
"""How long an ``expect`` keeps retrying by default (Playwright's own is 5 s)."""
expect.set_options(timeout=EXPECT_TIMEOUT_MS)

CHROMIUM = "/usr/bin/chromium"
CHROMIUM_ARGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    # WebGL (the mapping card's 3D view) in software, SwiftShader: Chromium 156 falls back
    # to it with --disable-gpu alone, but that fallback is deprecated, so it is asked by name.
    "--enable-unsafe-swiftshader",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--no-first-run",
]
SCREENSHOTS = BASE_DIR / "test-artifacts" / "screenshots"
VIEWPORT = {"width": 1440, "height": 960}
BUILDING = "boccioni_1"
ROBOT = "robot_0"
# The agent's simulated seconds per wall second: quick, yet teleop stays responsive.
TIME_SCALE = 3.0


MAP_ID = f"{BUILDING}/CorridorA"


@dataclass
class Demo:
    """The demo building seeded into the test database, its robots' tokens, and the session
    cookies (name, value) of its people."""

    server: LiveServer
    tokens: dict[str, str]
    cookies: dict[str, tuple[str, str]]

    def url(self, path: str) -> str:
        return self.server.url + path


@pytest.fixture
def demo(daphne_server: LiveServer, tmp_path: Path) -> Demo:
    """``seed_demo`` (building, users admin/operator/viewer, one robot) on the live server."""
    tokens = tmp_path / "tokens.json"
    call_command("seed_demo", "--robots", "1", "--tokens-file", str(tokens), stdout=io.StringIO())
    cookies = {}
    for user in User.objects.filter(username__in=["admin", "operator", "viewer"]):
        name, value = session_cookie(user).decode().split("=", 1)
        cookies[user.username] = (name, value)
    return Demo(daphne_server, json.loads(tokens.read_text()), cookies)


@pytest.fixture
def browser(demo: Demo) -> Iterator[Browser]:
    """Chromium, started once the database is ready (see the module's docstring)."""
    with sync_playwright() as playwright:
        launched = playwright.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        yield launched
        launched.close()


@pytest.fixture
def context(browser: Browser) -> Iterator[BrowserContext]:
    opened = browser.new_context(viewport=VIEWPORT)  # type: ignore[arg-type]
    opened.set_default_timeout(ACTION_TIMEOUT_MS)
    yield opened
    opened.close()


# The two sizes every page is tested at: a desktop and a phone.
PHONE = {"width": 390, "height": 844}
SIZES = [{"width": 1440, "height": 900}, PHONE]


@pytest.fixture
def phone(browser: Browser) -> Iterator[BrowserContext]:
    """A browser context at a phone's size (390x844), with a touch screen."""
    opened = browser.new_context(viewport=PHONE, has_touch=True)  # type: ignore[arg-type]
    opened.set_default_timeout(ACTION_TIMEOUT_MS)
    yield opened
    opened.close()


def touch_gesture(page: Page, selector: str, fingers: list[list[tuple[float, float]]]) -> None:
    """Fingers on ``selector`` as a touch screen reports them: ``fingers[i]`` is finger
    i's path, in pixels from the element's centre, one point per step."""
    box = page.locator(selector).bounding_box()
    assert box is not None
    cx, cy = box["x"] + box["width"] / 2, box["y"] + box["height"] / 2
    cdp = page.context.new_cdp_session(page)
    for step in range(len(fingers[0])):
        points = [
            {"x": cx + path[step][0], "y": cy + path[step][1], "id": finger + 1}
            for finger, path in enumerate(fingers)
        ]
        kind = "touchStart" if step == 0 else "touchMove"
        cdp.send("Input.dispatchTouchEvent", {"type": kind, "touchPoints": points})
    cdp.send("Input.dispatchTouchEvent", {"type": "touchEnd", "touchPoints": []})


def pinch(page: Page, selector: str) -> None:
    """Two fingers spreading apart on ``selector``."""
    spreads = [20 + 10 * step for step in range(8)]
    touch_gesture(page, selector, [[(-s, 0) for s in spreads], [(s, 0) for s in spreads]])


def swipe(page: Page, selector: str, dx: float) -> None:
    """One finger dragged ``dx`` pixels across ``selector``."""
    touch_gesture(page, selector, [[(dx * step / 8, 0.0) for step in range(9)]])


@pytest.fixture(params=SIZES, ids=["desktop", "phone"])
def sized(browser: Browser, request: pytest.FixtureRequest) -> Iterator[BrowserContext]:
    """A browser context at desktop (1440x900) or phone (390x844) size, with touch on the
    phone."""
    phone = request.param["width"] < 600
    opened = browser.new_context(viewport=request.param, has_touch=phone)
    opened.set_default_timeout(ACTION_TIMEOUT_MS)
    yield opened
    opened.close()


@pytest.fixture
def agent(demo: Demo, tmp_path: Path) -> Iterator[Path]:
    """The simulated robot ``robot_0`` in its own process, at the paper's start: before the
    entrance tag but too far to read it, so it is lost until it has a goal or an initial
    pose (``make demo``'s robots start nearer); yields its log file."""
    start = ",".join(str(v) for v in demo_building().start_pose)
    options = ["--time-scale", str(TIME_SCALE), "--camera-rate", "5", "--start", start]
    with agent_process(
        demo.server.url, demo.tokens[ROBOT], tmp_path / "agent.log", *options
    ) as log:
        yield log


@contextmanager
def speaking_robot(
    demo: Demo,
    speaking: threading.Event,
    goal_active: bool = False,
    *,
    token: str | None = None,
    at: tuple[str, float, float] = (MAP_ID, 2.0, 1.0),
) -> Iterator[None]:
    """``robot_0`` (or the robot of ``token``; no simulation, a rosbridge client) connects
    and, while ``speaking`` is set, publishes at 5 Hz that it stands still ``at`` (Map ID,
    x, y; in Corridor A unless told) and, if ``goal_active``, that it has an active goal;
    else it stays connected saying nothing, until the block ends."""
    done = threading.Event()
    map_id, x, y = at

    async def run() -> None:
        client = RosbridgeClient(demo.server.rosbridge_url(), token or demo.tokens[ROBOT])
        client.advertise("pose", "geometry_msgs/PoseStamped")
        client.advertise("nav_status", "actionlib_msgs/GoalStatusArray")
        task = asyncio.create_task(client.run())
        await asyncio.wait_for(client.wait_connected(), 10)
        pose = {"position": {"x": x, "y": y, "z": 0}, "orientation": {"w": 1.0}}
        goal = {"goal_id": {"id": "g1"}, "status": 1, "text": "driving"}
        status = {"header": {"frame_id": ""}, "status_list": [goal] if goal_active else []}
        while not done.is_set():
            if speaking.is_set():
                await client.publish("pose", {"header": {"frame_id": map_id}, "pose": pose})
                await client.publish("nav_status", status)
            await asyncio.sleep(0.2)
        await client.close()
        await task

    thread = threading.Thread(target=asyncio.run, args=(run(),))
    thread.start()
    try:
        yield
    finally:
        done.set()
        thread.join(20)


def open_as(context: BrowserContext, demo: Demo, username: str, path: str) -> Page:
    """A page of ``path`` for a signed-in demo user (session cookie set directly)."""
    name, value = demo.cookies[username]
    context.add_cookies([{"name": name, "value": value, "url": demo.server.url}])
    page = context.new_page()
    page.goto(demo.url(path))
    return page


def screenshot(page: Page, name: str) -> None:
    SCREENSHOTS.mkdir(parents=True, exist_ok=True)
    page.screenshot(path=str(SCREENSHOTS / f"{name}.png"), full_page=True)


def world_to_page(page: Page, canvas: str, x: float, y: float) -> tuple[float, float]:
    """Where the map point (x, y), in metres, is on the page, for mouse actions."""
    found: Any = page.evaluate(
        """([canvas, x, y]) => {
            const views = window.cloudnav.robotPage?.view || window.cloudnav.submapPage?.view;
            const rect = document.querySelector(canvas).getBoundingClientRect();
            const at = views.toScreen(x, y);
            return [rect.left + at.sx, rect.top + at.sy];
        }""",
        [canvas, x, y],
    )
    return float(found[0]), float(found[1])


def press_and_drag(page: Page, x: float, y: float, yaw: float, canvas: str = "#map-canvas") -> None:
    """Press on the map at (x, y) and drag one metre along ``yaw``: a pose tool's gesture."""
    start = world_to_page(page, canvas, x, y)
    end = world_to_page(page, canvas, x + math.cos(yaw), y + math.sin(yaw))
    page.mouse.move(*start)
    page.mouse.down()
    page.mouse.move(*end, steps=6)
    page.mouse.up()


def drawn_robot(page: Page) -> tuple[float, float] | None:
    """The robot's position as the map draws it, or None while it is not drawn."""
    value = page.get_attribute("#map-wrap", "data-robot")
    if not value:
        return None
    x, y = value.split(",")
    return float(x), float(y)


def topology_ids(page: Page, element: str, selector: str) -> list[str]:
    """The ids of what the cytoscape topology in ``#element`` draws for ``selector``
    (sub-maps ``node.submap``, edges ``edge``, classes ``.route``, ``.invalid``, ...)."""
    found: Any = page.evaluate(
        """([id, selector]) =>
            window.cloudnav.topologies[id].cy.elements(selector).map((e) => e.id())""",
        [element, selector],
    )
    return [str(value) for value in found]


def topology_point(page: Page, element: str, key: str) -> tuple[float, float]:
    """Where the node (a sub-map's code) or edge (``edgeKey``) ``key`` of the topology in
    ``#element`` is drawn on the page, for mouse actions."""
    found: Any = page.evaluate(
        """([id, key]) => {
            const view = window.cloudnav.topologies[id];
            const item = view.cy.getElementById(key);
            const at = item.isNode() ? item.renderedPosition() : item.renderedMidpoint();
            const rect = view.element.getBoundingClientRect();
            return [rect.left + at.x, rect.top + at.y];
        }""",
        [element, key],
    )
    return float(found[0]), float(found[1])
