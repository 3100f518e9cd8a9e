"""An operator with a simulated robot, in a real browser: goals, the live map, teleoperation
by keyboard and the camera (``python -m robots.agent`` against a live daphne)."""

from __future__ import annotations

import math
import re
from pathlib import Path

import pytest
from playwright.sync_api import BrowserContext, Page, expect

from tests.browser_support import (
    BUILDING,
    ROBOT,
    Demo,
    drawn_robot,
    open_as,
    press_and_drag,
    screenshot,
)

pytest_plugins = ["tests.browser_support"]
pytestmark = [pytest.mark.browser, pytest.mark.django_db(transaction=True)]

CORRIDOR_A = f"{BUILDING}/CorridorA"
START = (2.4, 22.6, 0.0)  # the demo robot's start pose, facing the entrance tag
GOAL = (8.0, 23.2, 0.0)
FAR_GOAL = (16.0, 23.2, 0.0)
BEYOND_THE_WALL = (10.0, 26.4, 0.0)  # 1.8 m north of Corridor A, outside the building
ATRIUM_1 = (20.0, 23.2, 0.0)  # between the door and the central pillar
SOMETHING = re.compile(r".+")


def robot_page(context: BrowserContext, demo: Demo) -> Page:
    page = open_as(context, demo, "operator", f"/robots/{ROBOT}/")
    expect(page.locator("#conn-state")).to_contain_text("Live")
    # The robot speaks only once it has subscribed to its commands.
    expect(page.locator("#robot-online")).to_have_text("online", timeout=30_000)
    expect(page.locator("#goal-map option[value='boccioni_1/CorridorA']")).to_be_attached()
    return page


def show_corridor_a(page: Page) -> None:
    page.select_option("#goal-map", CORRIDOR_A)
    expect(page.locator("#map-wrap")).to_have_attribute("data-loaded", CORRIDOR_A)


def localise(page: Page) -> None:
    """Tell the robot where it stands with the initial pose tool, and wait until it is drawn."""
    show_corridor_a(page)
    page.click("#map-tools button[data-tool=initialpose]")
    press_and_drag(page, *START)
    expect(page.locator("#robot-map")).to_have_text(CORRIDOR_A, timeout=20_000)
    expect(page.locator("#map-wrap")).to_have_attribute("data-robot", SOMETHING)


def distance_to(page: Page, x: float, y: float) -> float:
    where = drawn_robot(page)
    assert where is not None
    return math.hypot(where[0] - x, where[1] - y)


def wait_until_moved(page: Page, start: tuple[float, float], metres: float, timeout: int) -> None:
    """Wait until the robot drawn on the map stands more than ``metres`` from ``start``."""
    page.wait_for_function(
        """([x, y, metres]) => {
            const at = document.getElementById('map-wrap').dataset.robot;
            if (!at) return false;
            const [px, py] = at.split(',').map(Number);
            return Math.hypot(px - x, py - y) > metres;
        }""",
        arg=[start[0], start[1], metres],
        timeout=timeout,
    )


def test_an_operator_sends_a_goal_and_watches_the_robot_arrive(
    context: BrowserContext, demo: Demo, agent: Path
) -> None:
    page = robot_page(context, demo)
    show_corridor_a(page)
    page.click("#map-tools button[data-tool=goal]")
    press_and_drag(page, *GOAL)

    # The robot, which had no map, reads the entrance tag, appears on the map and moves.
    page.wait_for_function(
        "() => document.getElementById('map-wrap').dataset.robot", timeout=30_000
    )
    wait_until_moved(page, drawn_robot(page) or (0, 0), 1.0, timeout=30_000)
    expect(page.locator("#goal-state")).to_have_text("succeeded", timeout=60_000)
    assert distance_to(page, GOAL[0], GOAL[1]) < 0.5
    expect(page.locator("#robot-nav")).to_contain_text("succeeded")
    expect(page.locator("#rates-body tr[data-topic='/robot_0/pose']")).to_be_visible()
    expect(page.locator("#latency")).to_have_attribute("data-ms", SOMETHING)
    screenshot(page, "robot-goal-arrived")

    # A goal in the next sub-map: its route is drawn on the topology; then it is cancelled.
    page.select_option("#goal-map", f"{BUILDING}/Atrium1")
    expect(page.locator("#map-wrap")).to_have_attribute("data-loaded", f"{BUILDING}/Atrium1")
    page.click("#map-tools button[data-tool=goal]")
    press_and_drag(page, *ATRIUM_1)
    expect(page.locator("#route-label")).to_have_text("route: CorridorA → Atrium1")
    page.wait_for_function(
        "window.cloudnav.topologies['robot-topology'].cy.nodes('.route').length === 2"
    )
    expect(page.locator("#goal-state")).to_have_text("active", timeout=15_000)
    screenshot(page, "robot-goal-in-another-submap")
    page.click("#goal-cancel")
    expect(page.locator("#goal-text")).to_have_text("cancelled")
    expect(page.locator("#goal-state")).to_have_text("preempted", timeout=15_000)


def test_an_operator_takes_the_lock_and_drives_with_the_keyboard(
    context: BrowserContext, demo: Demo, agent: Path
) -> None:
    page = robot_page(context, demo)
    localise(page)
    page.click("#lock-acquire")
    expect(page.locator("#lock-state")).to_have_text("You are driving")
    before = drawn_robot(page)
    assert before is not None

    page.keyboard.down("ArrowUp")
    expect(page.locator("#keys kbd[data-direction=forward]")).to_have_class("on")
    wait_until_moved(page, before, 0.3, timeout=15_000)
    # uPlot draws the speed it drives at.
    expect(page.locator("#plot-linear .uplot canvas")).to_be_visible()
    page.wait_for_function(
        "window.cloudnav.robotPage.plots.linear.chart.data[1].some((speed) => speed > 0.05)"
    )
    screenshot(page, "robot-teleop")
    page.keyboard.up("ArrowUp")
    expect(page.locator("#odom-speed")).to_have_text("0.00 m/s", timeout=10_000)

    # The on-screen joystick drives too: pulled back, the robot reverses the way it came,
    # which is free whatever it drove up to. (Before any turn: after one, what lies behind
    # the robot depends on how long the turn lasted, which a loaded machine stretches.)
    before = drawn_robot(page)
    assert before is not None
    pad = page.locator("#joystick").bounding_box()
    assert pad is not None
    centre = (pad["x"] + pad["width"] / 2, pad["y"] + pad["height"] / 2)
    page.mouse.move(*centre)
    page.mouse.down()
    page.mouse.move(centre[0], centre[1] + pad["height"] / 2, steps=4)
    expect(page.locator("#odom-speed")).not_to_have_text("0.00 m/s", timeout=10_000)
    wait_until_moved(page, before, 0.05, timeout=15_000)
    page.mouse.up()
    page.click("#stop-button")
    expect(page.locator("#odom-speed")).to_have_text("0.00 m/s", timeout=10_000)
    expect(page.locator("#lock-state")).to_have_text("You are driving")

    # Someone else sees who holds the lock; asking for it tells the holder, who keeps it.
    # Only commands keep a lock (issue 23): the holder turns on the spot meanwhile.
    page.keyboard.down("ArrowLeft")
    other = open_as(context.browser.new_context(), demo, "admin", f"/robots/{ROBOT}/")  # type: ignore[union-attr]
    expect(other.locator("#conn-state")).to_contain_text("Live")
    expect(other.locator("#lock-state")).to_have_text("Driven by operator")
    other.click("#lock-acquire")
    expect(page.locator("#lock-message")).to_contain_text("admin asks for control")
    page.click("#lock-keep")
    expect(other.locator("#lock-message")).to_contain_text("user:operator keeps control")
    expect(other.locator("#lock-state")).to_have_text("Driven by operator")
    other.context.close()
    page.keyboard.up("ArrowLeft")

    page.click("#lock-release")
    expect(page.locator("#lock-state")).to_have_text("Not driving")
    expect(page.locator("#lock-acquire")).to_be_visible()


def test_the_camera_shows_frames_from_the_robot(
    context: BrowserContext, demo: Demo, agent: Path
) -> None:
    page = robot_page(context, demo)
    page.click("#camera-modes button[data-mode=topic]")
    page.wait_for_function(
        "() => Number(document.getElementById('camera-frame').dataset.frames || 0) >= 3",
        timeout=30_000,
    )
    # Each frame replaces the image's source, so wait for one that has finished decoding.
    page.wait_for_function(
        """() => {
            const img = document.querySelector('#camera-frame img');
            return img && img.complete && img.naturalWidth === 640;
        }""",
        timeout=10_000,
    )
    screenshot(page, "robot-camera")


@pytest.mark.parametrize("mode", ["mjpeg", "vp8"])
def test_the_camera_plays_the_video_relays(
    mode: str, context: BrowserContext, demo: Demo, agent: Path
) -> None:
    page = robot_page(context, demo)
    page.click(f"#camera-modes button[data-mode={mode}]")
    expect(page.locator("#camera-frame")).to_have_attribute("data-mode", mode)
    page.wait_for_function(
        "() => Number(document.getElementById('camera-frame').dataset.frames || 0) >= 3",
        timeout=30_000,
    )
    expect(page.locator("#camera-frame")).to_have_attribute("data-mode", mode)
    screenshot(page, f"robot-camera-{mode}")


def last_goal_id(page: Page) -> str | None:
    """The id of the newest goal in the robot's ``nav_status``, as the page received it."""
    found = page.evaluate(
        "() => window.cloudnav.robotPage.state.nav?.status_list.at(-1)?.goal_id.id ?? null"
    )
    return None if found is None else str(found)


def test_a_lost_robot_shows_the_way_out_and_a_goal_with_no_sub_map_is_refused(
    context: BrowserContext, demo: Demo, agent: Path
) -> None:
    page = robot_page(context, demo)
    banner = page.locator("#lost-banner")
    expect(banner).to_be_visible(timeout=20_000)
    expect(banner).to_contain_text("robot_0 is lost, looking for a tag.")
    expect(banner).to_contain_text("Way out")
    expect(banner).to_contain_text("drive it until its camera reads a tag")
    expect(page.locator("#robot-loc")).to_have_text("lost, looking for a tag")
    screenshot(page, "robot-lost")

    # No sub-map is shown: the Goal tool refuses, and pressing the map sends nothing.
    page.click("#map-tools button[data-tool=goal]")
    expect(page.locator("#map-hint")).to_contain_text("no sub-map is shown")
    expect(page.locator("#map-tools button[data-tool=goal]")).not_to_have_class(
        re.compile("active")
    )
    box = page.locator("#map-canvas").bounding_box()
    assert box is not None
    page.mouse.click(box["x"] + box["width"] / 2, box["y"] + box["height"] / 2)
    expect(page.locator("#goal-state")).to_have_text("idle")  # it never had a goal
    screenshot(page, "robot-goal-refused-without-a-submap")

    # The way out: choose the sub-map, set the initial pose from the banner.
    show_corridor_a(page)
    page.click("#lost-set-pose")
    press_and_drag(page, *START)
    expect(banner).to_be_hidden(timeout=20_000)
    expect(page.locator("#robot-loc")).to_have_text("localised")
    expect(page.locator("#loc-text")).to_have_text(f"localised in {CORRIDOR_A} by initial pose")

    # The first goal the robot ever got is this one: the refused press sent nothing.
    page.click("#map-tools button[data-tool=goal]")
    press_and_drag(page, *GOAL)
    expect(page.locator("#goal-state")).to_have_text(re.compile("active|succeeded"), timeout=15_000)
    assert last_goal_id(page) == "goal_1"


def test_a_goal_the_robot_cannot_reach_says_why_on_the_page(
    context: BrowserContext, demo: Demo, agent: Path
) -> None:
    """Beyond Corridor A's wall, outside the building: refused before it is sent (issue 23
    point 2), where the robot used to drive and then abort it."""
    page = robot_page(context, demo)
    localise(page)
    page.click("#map-tools button[data-tool=goal]")
    press_and_drag(page, *BEYOND_THE_WALL)
    hint = page.locator("#map-hint")
    expect(hint).to_be_visible()
    expect(hint).to_contain_text("Not sent")
    expect(page.locator("#goal-state")).not_to_have_text("active")
    screenshot(page, "robot-goal-refused-with-its-reason")


def test_space_stops_and_cancels_only_for_the_operator_holding_the_lock(
    context: BrowserContext, demo: Demo, agent: Path
) -> None:
    page = robot_page(context, demo)
    localise(page)
    page.click("#map-tools button[data-tool=goal]")
    press_and_drag(page, *FAR_GOAL)
    expect(page.locator("#goal-state")).to_have_text("active", timeout=15_000)

    # A viewer, and an operator without the lock, press Space: the robot drives on.
    viewer = open_as(context.browser.new_context(), demo, "viewer", f"/robots/{ROBOT}/")  # type: ignore[union-attr]
    expect(viewer.locator("#conn-state")).to_contain_text("Live")
    for someone in (viewer, page):
        someone.locator("body").press("Space")
        here = drawn_robot(page)
        assert here is not None
        wait_until_moved(page, here, 0.5, timeout=15_000)
        expect(page.locator("#goal-state")).to_have_text("active")
    viewer.context.close()

    # The operator holding the lock presses Space: it stops and its goal is cancelled.
    page.click("#lock-acquire")
    expect(page.locator("#lock-state")).to_have_text("You are driving")
    page.locator("body").press("Space")
    expect(page.locator("#goal-state")).to_have_text("preempted", timeout=15_000)
    expect(page.locator("#odom-speed")).to_have_text("0.00 m/s", timeout=10_000)
