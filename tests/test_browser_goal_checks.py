"""A click on a pillar is refused where it was pressed, before anything is sent: on the
robot's page (a goal in Atrium 1 for a robot in Corridor A) and on the building's floor
plan, at desktop and phone sizes, in a real browser against a live server. A goal pressed
where another robot stands is moved to the nearest free spot, said where it was pressed."""

from __future__ import annotations

import json
import math
import re
import threading

import pytest
from playwright.sync_api import BrowserContext, Page, expect

from maps.models import Building
from tests.browser_support import (
    BUILDING,
    ROBOT,
    Demo,
    open_as,
    press_and_drag,
    screenshot,
    speaking_robot,
)
from tests.conftest import make_robot
from tests.support.plan_page import open_plan, select_robot
from tests.support.plan_page import press_and_drag as press_and_drag_on_plan

pytest_plugins = ["tests.browser_support"]
pytestmark = [pytest.mark.browser, pytest.mark.django_db(transaction=True)]

ATRIUM_1 = f"{BUILDING}/Atrium1"
PILLAR = (20.2, 21.4, 0.0)  # the centre of one of Atrium 1's four pillars
# Pressed within a few pixels of it, whatever the screen's scale.
REFUSED = re.compile(r"The goal \(20\.\d+, 21\.\d+\) is in an obstacle")


def goals_sent(page: Page) -> list[dict]:
    """The goals the page publishes from now on (read from its WebSocket frames)."""
    sent: list[dict] = []

    def note(frame: str | bytes) -> None:
        try:
            message = json.loads(frame)
        except (TypeError, ValueError):
            return
        if message.get("op") == "publish" and str(message.get("topic")).endswith("/goal"):
            sent.append(message)

    page.on("websocket", lambda ws: ws.on("framesent", note))
    return sent


def test_the_robot_page_refuses_a_goal_on_a_pillar_where_it_was_pressed(
    sized: BrowserContext, demo: Demo
) -> None:
    page = open_as(sized, demo, "operator", f"/robots/{ROBOT}/")
    sent = goals_sent(page)
    page.reload()
    expect(page.locator("#conn-state")).to_contain_text("Live")
    expect(page.locator(f"#goal-map option[value='{ATRIUM_1}']")).to_be_attached()
    page.select_option("#goal-map", ATRIUM_1)
    expect(page.locator("#map-wrap")).to_have_attribute("data-loaded", ATRIUM_1)
    page.click("#map-tools button[data-tool=goal]")
    press_and_drag(page, *PILLAR)
    hint = page.locator("#map-hint")
    expect(hint).to_be_visible()
    expect(hint).to_contain_text(REFUSED)
    expect(page.locator("#goal-text")).to_contain_text("in an obstacle")
    screenshot(page, f"robot-goal-refused-{sized.pages[0].viewport_size['width']}")  # type: ignore[index]
    assert sent == []


def test_the_floor_plan_refuses_a_goal_on_a_pillar(sized: BrowserContext, demo: Demo) -> None:
    speaking = threading.Event()
    speaking.set()
    with speaking_robot(demo, speaking):
        page = open_plan(sized, demo)
        sent = goals_sent(page)
        page.reload()
        select_robot(page)
        page.click("#tool-goal")
        press_and_drag_on_plan(page, *PILLAR)
        expect(page.locator("#plan-hint")).to_contain_text("No goal sent: ")
        expect(page.locator("#plan-hint")).to_contain_text(REFUSED)
        expect(page.locator("#floor-plan")).to_have_attribute("data-refused", f"{ROBOT}:{ATRIUM_1}")
        assert sent == []


STANDING = (20.0, 23.2)  # in Atrium 1, between its door and the central pillar


@pytest.fixture
def other_robot(demo: Demo) -> str:
    """The token of ``robot_9``, a second robot of the demo building."""
    return make_robot(name="robot_9", buildings=[Building.objects.get(code=BUILDING)])[1]


def test_a_goal_where_another_robot_stands_is_moved_and_said_where_it_was_pressed(
    other_robot: str, context: BrowserContext, demo: Demo
) -> None:
    speaking = threading.Event()
    speaking.set()
    with speaking_robot(demo, speaking, token=other_robot, at=(ATRIUM_1, *STANDING)):
        page = open_as(context, demo, "operator", f"/robots/{ROBOT}/")
        sent = goals_sent(page)
        page.reload()
        expect(page.locator("#conn-state")).to_contain_text("Live")
        expect(page.locator(f"#goal-map option[value='{ATRIUM_1}']")).to_be_attached()
        page.select_option("#goal-map", ATRIUM_1)
        expect(page.locator("#map-wrap")).to_have_attribute("data-loaded", ATRIUM_1)
        page.click("#map-tools button[data-tool=goal]")
        press_and_drag(page, *STANDING, 0.0)
        hint = page.locator("#map-hint")
        expect(hint).to_have_attribute("data-moved", "true", timeout=15_000)
        expect(hint).to_contain_text("Moved to the nearest free spot")
        expect(hint).to_contain_text("robot_9 stands at (20.00, 23.20)")
        expect(page.locator("#goal-text")).to_contain_text("Moved to the nearest free spot")
        screenshot(page, "robot-goal-moved")
        [goal] = sent  # the spot the server gave, as the page sent it
        at = goal["msg"]["pose"]["position"]
        assert math.dist((at["x"], at["y"]), STANDING) >= 0.45  # pressed within pixels


def test_the_floor_plan_moves_a_goal_where_another_robot_stands_and_says_so(
    other_robot: str, context: BrowserContext, demo: Demo
) -> None:
    speaking = threading.Event()
    speaking.set()
    standing = speaking_robot(demo, speaking, token=other_robot, at=(ATRIUM_1, *STANDING))
    with speaking_robot(demo, speaking), standing:
        page = open_plan(context, demo)
        sent = goals_sent(page)
        page.reload()
        select_robot(page)
        page.click("#tool-goal")
        press_and_drag_on_plan(page, *STANDING, 0.0)
        plan = page.locator("#floor-plan")
        expect(plan).to_have_attribute("data-moved", f"{ROBOT}:{ATRIUM_1}", timeout=15_000)
        expect(page.locator("#plan-hint")).to_contain_text(f"Goal sent to {ROBOT} in Atrium1.")
        expect(page.locator("#plan-hint")).to_contain_text("robot_9 stands at (20.00, 23.20)")
        screenshot(page, "plan-goal-moved")
        [goal] = sent
        at = goal["msg"]["pose"]["position"]
        assert math.dist((at["x"], at["y"]), STANDING) >= 0.45
