"""Signing in, the fleet dashboard, the connection banner and what a viewer finds, in a
real browser against a live server with a simulated robot."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from playwright.sync_api import BrowserContext, WebSocketRoute, expect

from maps.domain.demo_building import demo_building
from tests.browser_support import ROBOT, Demo, open_as, press_and_drag, screenshot

pytest_plugins = ["tests.browser_support"]
pytestmark = [pytest.mark.browser, pytest.mark.django_db(transaction=True)]


def test_an_operator_signs_in_and_sees_the_robot_live_on_the_dashboard(
    context: BrowserContext, demo: Demo, agent: Path
) -> None:
    page = context.new_page()
    page.goto(demo.url("/"))
    expect(page).to_have_url(re.compile(r"/accounts/login/"))
    screenshot(page, "sign-in")
    page.fill("input[name=username]", "operator")
    page.fill("input[name=password]", "wrong")
    page.click("button[type=submit]")
    expect(page.locator(".alert.error")).to_be_visible()
    page.fill("input[name=username]", "operator")
    page.fill("input[name=password]", "operator-demo")
    page.click("button[type=submit]")

    expect(page).to_have_url(demo.url("/"))
    row = page.locator(f"#fleet-table tr[data-robot={ROBOT}]")
    expect(row).to_contain_text("online", timeout=30_000)
    expect(row.locator(".submap")).to_have_text("—")  # no map until it reads a tag
    expect(page.locator("#stat-online")).to_have_text("1")
    expect(page.locator("#conn-state")).to_contain_text("Live")
    screenshot(page, "fleet-dashboard")

    row.click()
    expect(page).to_have_url(demo.url(f"/robots/{ROBOT}/"))


def test_a_lost_connection_shows_a_banner_and_reconnects(
    context: BrowserContext, demo: Demo
) -> None:
    sockets: list[WebSocketRoute] = []

    def relay(socket: WebSocketRoute) -> None:
        socket.connect_to_server()
        sockets.append(socket)

    context.route_web_socket(re.compile(r"/rosbridge$"), relay)
    page = open_as(context, demo, "operator", "/")
    expect(page.locator("#conn-state")).to_contain_text("Live")
    expect(page.locator("#ws-banner")).to_be_hidden()

    sockets[-1].close(code=1006, reason="network lost")
    expect(page.locator("#ws-banner")).to_be_visible()
    expect(page.locator("#ws-banner")).to_contain_text("reconnecting")
    expect(page.locator("#conn-state")).to_contain_text("Offline")
    screenshot(page, "fleet-connection-lost")

    expect(page.locator("#conn-state")).to_contain_text("Live", timeout=15_000)
    expect(page.locator("#ws-banner")).to_be_hidden()
    assert len(sockets) >= 2


def test_a_viewer_finds_no_controls(context: BrowserContext, demo: Demo, agent: Path) -> None:
    commands: list[str] = []
    page = open_as(context, demo, "viewer", f"/robots/{ROBOT}/")
    page.on("websocket", lambda ws: ws.on("framesent", lambda frame: commands.append(str(frame))))
    page.reload()
    expect(page.locator("#robot-online")).to_have_text("online", timeout=30_000)
    expect(page.locator("#map-canvas")).to_be_visible()
    expect(page.locator("#camera-card")).to_be_visible()
    for control in ("#teleop-card", "#stop-button", "#goal-card", "#map-tools", "#lock-acquire"):
        expect(page.locator(control)).to_have_count(0)
    page.keyboard.press("ArrowUp")
    page.keyboard.press("KeyW")
    screenshot(page, "robot-viewer")

    page.goto(demo.url("/buildings/"))
    expect(page.locator(".building-card")).to_have_count(1)
    screenshot(page, "buildings-viewer")
    page.goto(demo.url("/buildings/boccioni_1/"))
    page.wait_for_function("window.cloudnav.topologies.topology.cy.nodes('.submap').length === 10")
    for editor in ("#topology-save", "#edge-editor", "#upload-link"):
        expect(page.locator(editor)).to_have_count(0)
    page.goto(demo.url("/buildings/boccioni_1/maps/CorridorA/"))
    expect(page.locator("#map-wrap")).to_have_attribute("data-loaded", "CorridorA")
    expect(page.locator("#place-tag")).to_have_count(0)
    expect(page.locator("#tag-save")).to_have_count(0)
    assert not [frame for frame in commands if re.search(r'"op":\s*"publish"', frame)]
    assert page.goto(demo.url("/buildings/boccioni_1/upload/")).status == 403  # type: ignore[union-attr]


def test_the_page_asks_to_sign_in_again_when_signed_out(
    context: BrowserContext, demo: Demo
) -> None:
    page = open_as(context, demo, "admin", "/")
    page.click("text=Sign out")
    expect(page).to_have_url(re.compile(r"/accounts/login/"))
    page.goto(demo.url("/buildings/"))
    expect(page).to_have_url(re.compile(r"/accounts/login/\?next=/buildings/"))


def test_the_dashboard_says_which_robot_is_lost_and_the_way_out(
    context: BrowserContext, demo: Demo, agent: Path
) -> None:
    # The agent's robot starts too far from the entrance tag to read it: lost.
    page = open_as(context, demo, "viewer", "/")
    row = page.locator(f"#fleet-table tr[data-robot={ROBOT}]")
    cell = row.locator(".localisation")
    expect(cell.locator(".badge")).to_have_text("lost, looking for a tag", timeout=30_000)
    expect(cell).to_contain_text("An operator can set its initial pose, or drive it to a tag.")
    expect(page.locator("#stat-lost")).to_have_text("1")
    screenshot(page, "fleet-dashboard-robot-lost")

    operator = open_as(context, demo, "operator", f"/robots/{ROBOT}/")
    expect(operator.locator("#robot-online")).to_have_text("online", timeout=30_000)
    operator.select_option("#goal-map", "boccioni_1/CorridorA")
    expect(operator.locator("#map-wrap")).to_have_attribute("data-loaded", "boccioni_1/CorridorA")
    operator.click("#lost-set-pose")
    press_and_drag(operator, *demo_building().start_pose)
    expect(cell.locator(".badge")).to_have_text("localised", timeout=20_000)
    expect(page.locator("#stat-lost")).to_have_text("0")
