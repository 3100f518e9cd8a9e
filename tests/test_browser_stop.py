"""STOP on a phone halts the robot whoever sent its goal: a goal sent from the building's
floor plan is stopped from the robot's page, and one sent again is stopped from the floor
plan, both at a phone's size, in a real browser against a live server and the simulated
robot (``python -m robots.agent``)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
from playwright.sync_api import Browser, BrowserContext, Page, expect

from tests.browser_support import ACTION_TIMEOUT_MS, BUILDING, ROBOT, Demo, open_as, screenshot
from tests.support.plan_page import open_plan, press_and_drag, select_robot

pytest_plugins = ["tests.browser_support"]
pytestmark = [pytest.mark.browser, pytest.mark.django_db(transaction=True)]

PHONE = {"width": 390, "height": 844}
FAR_GOAL = (16.0, 23.2, 0.0)  # the far end of Corridor A


@pytest.fixture
def phone(browser: Browser) -> Any:
    opened = browser.new_context(viewport=PHONE, has_touch=True)  # type: ignore[arg-type]
    opened.set_default_timeout(ACTION_TIMEOUT_MS)
    yield opened
    opened.close()


def send_goal_from_the_plan(plan: Page) -> None:
    plan.click("#tool-goal")
    press_and_drag(plan, *FAR_GOAL)
    expect(plan.locator("#floor-plan")).to_have_attribute(
        "data-goal", f"{ROBOT}:{BUILDING}/CorridorA"
    )


def navigation(page: Page) -> Any:
    return expect(page.locator("#robot-nav"))


def test_stop_on_a_phone_halts_a_goal_sent_from_another_page(
    context: BrowserContext, phone: BrowserContext, demo: Demo, agent: Path
) -> None:
    plan = open_plan(context, demo, "operator")
    select_robot(plan)
    send_goal_from_the_plan(plan)

    # The admin's phone, on the robot's page: the goal came from another page and person.
    robot_page = open_as(phone, demo, "admin", f"/robots/{ROBOT}/")
    navigation(robot_page).to_contain_text("active", timeout=45_000)
    robot_page.click("#stop-button")
    navigation(robot_page).to_contain_text("preempted", timeout=15_000)
    expect(robot_page.locator("#odom-speed")).to_have_text("0.00 m/s", timeout=10_000)
    expect(robot_page.locator("#goal-text")).to_contain_text("Stopped: ")
    expect(robot_page.locator("#goal-text")).to_contain_text("goal: cancelled")
    screenshot(robot_page, "stop-phone-robot-page")

    # Again, stopped this time from the floor plan on the phone.
    send_goal_from_the_plan(plan)
    navigation(robot_page).to_contain_text("active", timeout=15_000)
    phone_plan = open_plan(phone, demo, "operator")
    select_robot(phone_plan)
    stop = phone_plan.locator("#selected-stop")
    expect(stop).to_be_in_viewport()
    stop.click()
    expect(phone_plan.locator("#plan-hint")).to_contain_text(f"{ROBOT} stopped: ")
    navigation(robot_page).to_contain_text("preempted", timeout=15_000)
    expect(robot_page.locator("#odom-speed")).to_have_text("0.00 m/s", timeout=10_000)
    screenshot(phone_plan, "stop-phone-floor-plan")
