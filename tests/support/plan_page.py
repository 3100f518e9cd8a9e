"""The building map page in a browser: open the plan, select a robot, press and drag a
goal."""

from __future__ import annotations

import math

from playwright.sync_api import BrowserContext, Page, expect

from maps.domain.demo_building import demo_building
from tests.browser_support import BUILDING, ROBOT, Demo, open_as

PAGE = f"/buildings/{BUILDING}/map/"


def open_plan(context: BrowserContext, demo: Demo, user: str = "operator") -> Page:
    page = open_as(context, demo, user, PAGE)
    codes = ",".join(sorted(s.code for s in demo_building().submaps))
    page.wait_for_function(
        "(codes) => (document.getElementById('floor-plan').dataset.loaded || '')"
        ".split(',').sort().join(',') === codes",
        arg=codes,
    )
    return page


def press_and_drag(page: Page, x: float, y: float, yaw: float) -> None:
    """Press on the plan at building point (x, y) and drag half a metre along ``yaw``."""
    page.locator("#floor-plan").scroll_into_view_if_needed()
    start, end = page.evaluate(
        """([x, y, x2, y2]) => [window.cloudnav.floorPlan.toPage(x, y),
                                window.cloudnav.floorPlan.toPage(x2, y2)]""",
        [x, y, x + 0.5 * math.cos(yaw), y + 0.5 * math.sin(yaw)],
    )
    page.mouse.move(*start)
    page.mouse.down()
    page.mouse.move(*end, steps=5)
    page.mouse.up()


def select_robot(page: Page, name: str = ROBOT) -> None:
    """Wait until the robot speaks (it then listens to its goals), and select it in the list."""
    row = page.locator(f"#robot-list tr[data-robot={name}]")
    expect(row).not_to_have_attribute("data-state", "no data", timeout=30_000)
    row.click()
    expect(page.locator("#selected-name")).to_have_text(name)
