"""Robot state is shown as live only while it is: on the building page a robot is online,
and on the sub-map it says, only while the page hears from it (whatever the server's
record of its connection), and a lost server connection is said on every live element of
every live page; in a real browser at desktop and phone sizes."""

from __future__ import annotations

import re
import threading

import pytest
from playwright.sync_api import BrowserContext, Page, WebSocketRoute, expect

from tests.browser_support import BUILDING, ROBOT, Demo, open_as, screenshot, speaking_robot

pytest_plugins = ["tests.browser_support"]
pytestmark = [pytest.mark.browser, pytest.mark.django_db(transaction=True)]

# The robots the building page's topology (cytoscape) draws on its sub-maps.
MARKERS = "window.cloudnav.topologies.topology.cy.nodes('.robot-marker')"
LIVE_PAGES = ["/", f"/buildings/{BUILDING}/", f"/buildings/{BUILDING}/map/", f"/robots/{ROBOT}/"]


def server_says_online(page: Page) -> bool:
    entries = page.request.get(page.url.split("/buildings/")[0] + "/api/fleet/").json()
    return bool(next(e for e in entries if e["robot"] == ROBOT)["online"])


def test_the_building_page_shows_a_robot_online_only_while_it_is_heard(
    sized: BrowserContext, demo: Demo
) -> None:
    speaking = threading.Event()
    speaking.set()
    with speaking_robot(demo, speaking):
        page = open_as(sized, demo, "operator", f"/buildings/{BUILDING}/")
        row = page.locator(f"#building-robots tr[data-robot={ROBOT}]")
        expect(row).to_have_attribute("data-state", "online", timeout=20_000)
        expect(row.locator(".submap")).to_have_text("CorridorA")
        page.wait_for_function(f"{MARKERS}.map((m) => m.data('on')).join() === 'CorridorA'")
        width = page.viewport_size["width"]  # type: ignore[index]
        screenshot(page, f"building-robots-live-{width}")

        speaking.clear()
        expect(row).to_have_attribute("data-state", re.compile(r"^silent \d+ s$"), timeout=10_000)
        expect(row.locator(".submap")).to_have_text("last: CorridorA")
        page.wait_for_function(f"{MARKERS}.length === 0")
        # The server still holds the connection, and its record says online: the page
        # goes by what it hears.
        assert server_says_online(page)
        screenshot(page, f"building-robots-silent-{width}")


@pytest.mark.parametrize("path", LIVE_PAGES)
def test_a_lost_server_is_said_on_every_live_element(
    sized: BrowserContext, demo: Demo, path: str
) -> None:
    sockets: list[WebSocketRoute] = []

    def relay(socket: WebSocketRoute) -> None:
        socket.connect_to_server()
        sockets.append(socket)

    sized.route_web_socket(re.compile(r"/rosbridge$"), relay)
    page = open_as(sized, demo, "operator", path)
    expect(page.locator("#conn-state")).to_contain_text("Live")
    live = page.locator(".live-element:visible")
    expect(live.first).to_be_visible()
    expect(page.locator(".live-lost:visible")).to_have_count(0)

    sockets[-1].close(code=1006, reason="network lost")
    expect(page.locator("body")).to_have_class(re.compile("server-lost"))
    count = live.count()
    assert count >= 1
    notes = page.locator(".live-element:visible > .live-lost")
    expect(notes).to_have_count(count)
    for index in range(count):
        expect(notes.nth(index)).to_have_text("Not connected to the server: not live.")
        expect(notes.nth(index)).to_be_visible()
    name = path.strip("/").replace("/", "-") or "fleet"
    screenshot(page, f"server-lost-{name}-{page.viewport_size['width']}")  # type: ignore[index]

    expect(page.locator("#conn-state")).to_contain_text("Live", timeout=15_000)
    expect(page.locator(".live-lost:visible")).to_have_count(0)
