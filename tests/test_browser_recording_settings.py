"""A building's admin sets recording (what, camera rate, retention) on the building's page,
in Chromium at desktop and phone size; a viewer sees the settings and cannot change them."""

from __future__ import annotations

import pytest
from playwright.sync_api import BrowserContext, expect

from tests.browser_support import BUILDING, Demo, open_as, screenshot

pytest_plugins = ["tests.browser_support"]
pytestmark = [pytest.mark.browser, pytest.mark.django_db(transaction=True)]

PAGE = f"/buildings/{BUILDING}/"
API = f"/api/buildings/{BUILDING}/recording/"


def test_an_admin_sets_recording_on_the_buildings_page(sized: BrowserContext, demo: Demo) -> None:
    page = open_as(sized, demo, "admin", PAGE)
    card = page.locator("#recording-card")
    expect(card.locator("input[data-topic=scan]")).to_be_checked()
    expect(page.locator("#recording-days")).to_have_value("14")
    card.locator("input[data-topic=scan]").uncheck()
    card.locator("input[data-topic=battery]").check()
    page.fill("#recording-camera", "2")
    page.fill("#recording-days", "7")
    page.fill("#recording-budget", "2048")
    card.scroll_into_view_if_needed()
    page.click("#recording-save")
    expect(page.locator("#recording-saved")).to_contain_text("Saved")
    width = sized.pages[0].viewport_size["width"] if sized.pages[0].viewport_size else 0
    screenshot(page, f"building-recording-settings-{width}")
    assert card.bounding_box()["width"] <= width  # type: ignore[index]

    stored = page.request.get(demo.url(API)).json()
    assert "scan" not in stored["topics"]
    assert "battery" in stored["topics"]
    assert (stored["camera_rate"], stored["retention_days"], stored["budget_mb"]) == (2.0, 7, 2048)
    page.reload()
    expect(page.locator("#recording-days")).to_have_value("7")
    expect(card.locator("input[data-topic=scan]")).not_to_be_checked()


def test_a_viewer_sees_recording_but_cannot_change_it(sized: BrowserContext, demo: Demo) -> None:
    page = open_as(sized, demo, "viewer", PAGE)
    expect(page.locator("#recording-card input[data-topic=pose]")).to_be_checked()
    expect(page.locator("#recording-enabled")).to_be_disabled()
    expect(page.locator("#recording-days")).to_be_disabled()
    expect(page.locator("#recording-save")).to_have_count(0)
    expect(page.locator("#recording-readonly")).to_be_visible()
    refused = page.request.patch(demo.url(API), data={"enabled": False})
    assert refused.status == 403
