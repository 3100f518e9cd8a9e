"""Parking spots on the building's live map: an admin places one by tapping the plan,
drags it and deletes it, at desktop and phone sizes; a viewer sees them and edits none.
A real browser against a live server."""

from __future__ import annotations

import pytest
from playwright.sync_api import BrowserContext, Page, expect

from maps.domain.demo_building import demo_building
from tests.browser_support import BUILDING, Demo, screenshot
from tests.support.plan_page import open_plan, press_and_drag

pytest_plugins = ["tests.browser_support"]
pytestmark = [pytest.mark.browser, pytest.mark.django_db(transaction=True)]

SPOT = (10.8, 23.2)  # the middle of Corridor A
DRAGGED_TO = (12.4, 22.8)
SEEDED = {spot.name for spot in demo_building().parking}  # the demo's own, in the atria


def stored_spots(page: Page, demo: Demo) -> dict[str, dict]:
    """The building's parking spots as the server holds them (the page's session asks),
    by name."""
    spots = page.request.get(demo.url(f"/api/buildings/{BUILDING}/parking/")).json()
    return {spot["name"]: spot for spot in spots}


def near(spot: dict, point: tuple[float, float]) -> bool:
    return abs(spot["x"] - point[0]) < 0.1 and abs(spot["y"] - point[1]) < 0.1


def spot_at(page: Page, name: str) -> tuple[float, float]:
    """Where the marker of spot ``name`` is on the page."""
    box = page.locator(f".parking-spot[data-spot='{name}']").bounding_box()
    assert box is not None
    return box["x"] + box["width"] / 2, box["y"] + box["height"] / 2


def test_an_admin_places_drags_and_deletes_a_parking_spot(sized: BrowserContext, demo: Demo):
    page = open_plan(sized, demo, "admin")
    page.locator("#tool-parking").click()
    press_and_drag(page, *SPOT, 0.0)
    expect(page.locator("#parking-list tr[data-spot=P1]")).to_contain_text("CorridorA")
    spots = stored_spots(page, demo)
    assert set(spots) == {*SEEDED, "P1"}
    assert spots["P1"]["map"] == "CorridorA"
    assert near(spots["P1"], SPOT)
    screenshot(page, f"parking-placed-{(page.viewport_size or {'width': 0})['width']}")

    target = page.evaluate("([x, y]) => window.cloudnav.floorPlan.toPage(x, y)", DRAGGED_TO)
    page.mouse.move(*spot_at(page, "P1"))
    page.mouse.down()
    page.mouse.move(*target, steps=8)
    page.mouse.up()
    expect(page.locator("#plan-hint")).to_have_text("Parking spot P1 moved.")
    assert near(stored_spots(page, demo)["P1"], DRAGGED_TO)

    page.locator("#parking-list tr[data-spot=P1] button").click()
    expect(page.locator("#parking-list tr[data-spot=P1]")).to_have_count(0)
    assert set(stored_spots(page, demo)) == SEEDED


def test_a_spot_in_a_wall_is_refused_with_the_reason(context: BrowserContext, demo: Demo):
    page = open_plan(context, demo, "admin")
    page.locator("#tool-parking").click()
    press_and_drag(page, 10.8, 21.95, 0.0)  # Corridor A's south wall
    expect(page.locator("#plan-hint")).to_contain_text("No parking spot placed:")
    assert set(stored_spots(page, demo)) == SEEDED


def test_a_viewer_sees_the_spots_and_edits_none(context: BrowserContext, demo: Demo):
    admin = open_plan(context, demo, "admin")
    admin.locator("#tool-parking").click()
    press_and_drag(admin, *SPOT, 0.0)
    expect(admin.locator("#parking-list tr[data-spot=P1]")).to_be_visible()
    context.clear_cookies()
    page = open_plan(context, demo, "viewer")
    expect(page.locator("#parking-list tr[data-spot=P1]")).to_be_visible()
    expect(page.locator("#tool-parking")).to_have_count(0)
    expect(page.locator("#parking-list button")).to_have_count(0)
    expect(page.locator(".parking-spot[data-spot=P1]")).not_to_have_class(
        "leaflet-marker-draggable"
    )
