"""The relays in Chromium, with the simulated robot ``robot_0`` publishing its camera: the
MJPEG ``<img>`` changes and the VP8 player's ``currentTime`` advances, on the relay's
viewer page and in the robot page's camera panel."""

from __future__ import annotations

from pathlib import Path

import pytest
from playwright.sync_api import BrowserContext, expect

from tests.browser_support import Demo, open_as, screenshot

pytest_plugins = ["tests.browser_support"]
pytestmark = [pytest.mark.browser, pytest.mark.django_db(transaction=True)]

TOPIC = "/robot_0/camera/image/compressed"

# A tiny sample of the picture, to tell one frame from the next.
SAMPLE = """img => {
    const canvas = document.createElement('canvas');
    canvas.width = 16; canvas.height = 12;
    const ctx = canvas.getContext('2d');
    ctx.drawImage(img, 0, 0, 16, 12);
    return Array.from(ctx.getImageData(0, 0, 16, 12).data).join(',');
}"""


def test_the_mjpeg_image_changes_on_the_viewer_page(
    context: BrowserContext, demo: Demo, agent: Path
) -> None:
    page = open_as(context, demo, "viewer", f"/stream_viewer?topic={TOPIC}&type=mjpeg")
    image = page.locator("img#stream")
    page.wait_for_function(
        "() => document.querySelector('img#stream').naturalWidth > 0", timeout=30_000
    )
    assert image.evaluate("img => img.naturalWidth") == 640
    screenshot(page, "video-viewer-mjpeg")
    first = image.evaluate(SAMPLE)
    page.wait_for_function(
        f"([img, first]) => ({SAMPLE})(img) !== first",
        arg=[image.element_handle(), first],
        timeout=15_000,
    )


def test_the_vp8_player_advances_on_the_viewer_page(
    context: BrowserContext, demo: Demo, agent: Path
) -> None:
    page = open_as(context, demo, "viewer", f"/stream_viewer?topic={TOPIC}&type=vp8")
    page.wait_for_function(
        "() => document.querySelector('video#stream').currentTime > 0.5", timeout=30_000
    )
    now = page.evaluate("() => document.querySelector('video#stream').currentTime")
    page.wait_for_function(
        "t => document.querySelector('video#stream').currentTime > t + 0.5", arg=now, timeout=15_000
    )
    assert page.evaluate("() => document.querySelector('video#stream').videoWidth") == 640
    expect(page.locator("#stream-stats")).to_contain_text("fps", timeout=15_000)
    screenshot(page, "video-viewer-vp8")


def test_the_robot_pages_vp8_player_advances_and_shows_the_streams_figures(
    context: BrowserContext, demo: Demo, agent: Path
) -> None:
    page = open_as(context, demo, "viewer", "/robots/robot_0/")
    page.click("#camera-modes button[data-mode=vp8]")
    video = "document.querySelector('#camera-frame video')"
    page.wait_for_function(f"() => {video} && {video}.currentTime > 0.5", timeout=30_000)
    now = page.evaluate(f"() => {video}.currentTime")
    page.wait_for_function(f"t => {video}.currentTime > t + 0.5", arg=now, timeout=15_000)
    expect(page.locator("#camera-stats")).to_contain_text("fps", timeout=15_000)
    screenshot(page, "video-robot-page-vp8")


def test_the_camera_page_lists_the_robots_camera(
    context: BrowserContext, demo: Demo, agent: Path
) -> None:
    robot_page = open_as(context, demo, "viewer", "/robots/robot_0/")
    robot_page.wait_for_function(  # the robot publishes its camera by now
        "() => Number(document.getElementById('camera-frame').dataset.frames || 0) >= 1",
        timeout=30_000,
    )
    page = open_as(context, demo, "viewer", "/video/")
    row = page.locator(f"#camera-topics tr[data-topic='{TOPIC}']")
    expect(row.locator(".badge")).to_have_text("publishing")
    screenshot(page, "video-cameras")
    row.get_by_role("link", name="VP8", exact=True).click()
    expect(page.locator("video#stream")).to_be_attached()
