"""WebRTC in Chromium, with the simulated robot ``robot_0`` publishing its camera: the robot
page's camera panel plays it by default (by WHEP) and shows what it measures; the viewer
page offers it; when WebRTC fails the panel falls back to MJPEG by itself."""

from __future__ import annotations

from pathlib import Path

import pytest
from playwright.sync_api import BrowserContext, Route, expect

from tests.browser_support import Demo, open_as, screenshot

pytest_plugins = ["tests.browser_support"]
pytestmark = [pytest.mark.browser, pytest.mark.django_db(transaction=True)]

TOPIC = "/robot_0/camera/image/compressed"
VIDEO = "document.querySelector('#camera-frame video')"


def presented(page) -> int:
    return int(page.get_attribute("#camera-frame", "data-frames") or 0)


def test_the_robot_page_plays_webrtc_by_default_and_shows_its_figures(
    context: BrowserContext, demo: Demo, agent: Path
) -> None:
    page = open_as(context, demo, "viewer", "/robots/robot_0/")
    expect(page.locator("#camera-modes button.active")).to_have_attribute("data-mode", "webrtc")
    page.wait_for_function(f"() => {VIDEO} && {VIDEO}.videoWidth > 0", timeout=30_000)
    assert page.evaluate(f"() => [{VIDEO}.videoWidth, {VIDEO}.videoHeight]") == [640, 480]
    shown = presented(page)
    page.wait_for_function(
        "n => Number(document.getElementById('camera-frame').dataset.frames || 0) > n + 2",
        arg=shown,
        timeout=15_000,
    )
    expect(page.locator("#camera-rtc")).to_contain_text("kbit/s", timeout=15_000)
    expect(page.locator("#camera-rtc")).to_contain_text("VP8")
    expect(page.locator("#camera-stats")).to_contain_text("webrtc/vp8", timeout=15_000)
    assert page.get_attribute("#camera-frame", "data-fallback") is None
    screenshot(page, "robot-camera-webrtc")


def test_the_panel_falls_back_to_mjpeg_when_webrtc_fails(
    context: BrowserContext, demo: Demo, agent: Path
) -> None:
    def refuse(route: Route) -> None:
        route.fulfill(status=503, body="no WebRTC here\n")

    context.route("**/whep?*", refuse)
    page = open_as(context, demo, "viewer", "/robots/robot_0/")
    expect(page.locator("#camera-frame")).to_have_attribute("data-fallback", "mjpeg")
    expect(page.locator("#camera-frame")).to_have_attribute("data-mode", "mjpeg")
    page.wait_for_function(
        "() => document.querySelector('#camera-frame img')?.naturalWidth > 0", timeout=30_000
    )


def test_the_viewer_page_offers_webrtc(context: BrowserContext, demo: Demo, agent: Path) -> None:
    page = open_as(context, demo, "viewer", f"/stream_viewer?topic={TOPIC}&type=webrtc")
    page.wait_for_function(
        "() => document.querySelector('video#stream')?.videoWidth > 0", timeout=30_000
    )
    assert page.evaluate("() => document.querySelector('video#stream').videoWidth") == 640
    now = page.evaluate("() => document.querySelector('video#stream').currentTime")
    page.wait_for_function(
        "t => document.querySelector('video#stream').currentTime > t + 0.5", arg=now, timeout=15_000
    )
    expect(page.locator("#stream-stats")).to_contain_text("fps", timeout=15_000)
