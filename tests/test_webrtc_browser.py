"""WebRTC in Chromium, with the simulated robot ``robot_0`` publishing its camera: the robot
page's camera panel plays it by default (by WHEP) and shows what it measures; the viewer
page offers it; when WebRTC fails the panel falls back to MJPEG by itself. With
``--camera-timecode`` the robot stamps the wall clock into each picture and the panel reads
it back from the pictures it shows: the glass-to-glass delay, held to a bound."""

from __future__ import annotations

import asyncio
import threading
import time
import urllib.request
from collections.abc import Iterator
from pathlib import Path

import pytest
from playwright.sync_api import BrowserContext, Page, Route, expect

from tests.browser_support import ROBOT, TIME_SCALE, Demo, open_as, screenshot
from tests.fixtures_live import agent_process, video_stats
from tests.support.camera_feed import Camera, camera_frames

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


# ---------------------------------------------------------------- glass to glass

# Glass-to-glass bounds of the browser tests. The target (p95 at most 150 ms) is
# the benchmark's, on a quiet machine (`bench webrtc`: p95 about 45 ms). These tests share
# two cores with a simulated robot and whatever else runs (a load average of 20 was seen
# while they ran: p95 454 ms), so they hold the pictures to bounds that a relay or player
# keeping even a second of video (as a plain <video> on WebM does, about 2 s) still breaks.
GLASS_TO_GLASS_P50_MS = 400
GLASS_TO_GLASS_P95_MS = 1000


@pytest.fixture
def stamping_agent(demo: Demo, tmp_path: Path) -> Iterator[Path]:
    """The simulated robot ``robot_0`` with ``--camera-timecode``: its camera stamps the wall
    clock into each picture."""
    options = ["--time-scale", str(TIME_SCALE), "--camera-rate", "5", "--camera-timecode"]
    with agent_process(
        demo.server.url, demo.tokens[ROBOT], tmp_path / "agent.log", *options
    ) as log:
        yield log


def wait_for_camera(demo: Demo, wait: float = 60.0) -> None:
    """Return once the robot's camera has published a picture (its ``/snapshot`` answers)."""
    request = urllib.request.Request(
        demo.url(f"/snapshot?topic={TOPIC}"),
        headers={"Authorization": f"Token {demo.tokens[ROBOT]}"},
    )
    give_up = time.monotonic() + wait
    while time.monotonic() < give_up:
        try:
            with urllib.request.urlopen(request, timeout=5) as response:
                if response.status == 200:
                    return
        except OSError:  # a 404 before the robot is there, or a snapshot that waited too long
            pass
        time.sleep(0.2)
    raise AssertionError(f"{ROBOT}'s camera published nothing in {wait} s")


def glass_to_glass(page: Page, pictures: int) -> tuple[float, float]:
    """The camera panel's delay p50 and p95 (ms) over its window (the last 10 s), once the
    stream has run (10 time codes read) and then ``pictures`` more were read: the window
    then holds none of the first pictures, which the starting robot and the browser's
    jitter buffer, still settling, delay by up to a second or so."""
    count = "Number(document.getElementById('camera-frame').dataset.delayCount || 0)"
    page.wait_for_function(f"() => {count} >= 10", timeout=60_000)  # the robot starts
    started = int(page.get_attribute("#camera-frame", "data-delay-count") or 0)
    page.wait_for_function(f"n => {count} >= n", arg=started + pictures, timeout=60_000)
    frame = page.locator("#camera-frame")
    return float(frame.get_attribute("data-delay-p50") or "nan"), float(
        frame.get_attribute("data-delay-p95") or "nan"
    )


def assert_within_bounds(p50: float, p95: float) -> None:
    assert 0 < p50 <= p95, (p50, p95)
    assert p50 < GLASS_TO_GLASS_P50_MS, p50
    assert p95 < GLASS_TO_GLASS_P95_MS, p95


def test_the_panel_reads_the_time_code_back_and_the_webrtc_delay_is_bounded(
    context: BrowserContext, demo: Demo, stamping_agent: Path
) -> None:
    wait_for_camera(demo)
    page = open_as(context, demo, "viewer", "/robots/robot_0/")
    expect(page.locator("#camera-frame")).to_have_attribute("data-mode", "webrtc")
    p50, p95 = glass_to_glass(page, 60)
    assert page.get_attribute("#camera-frame", "data-fallback") is None, page.get_attribute(
        "#camera-frame", "data-fallback-reason"
    )
    assert_within_bounds(p50, p95)
    expect(page.locator("#camera-fps")).to_contain_text("Glass to glass")
    screenshot(page, "robot-camera-glass-to-glass")


def test_the_panel_reads_the_time_code_from_mjpeg_too(
    context: BrowserContext, demo: Demo, stamping_agent: Path
) -> None:
    wait_for_camera(demo)
    page = open_as(context, demo, "viewer", "/robots/robot_0/")
    page.click("#camera-modes button[data-mode=mjpeg]")
    p50, p95 = glass_to_glass(page, 60)
    assert_within_bounds(p50, p95)


# ---------------------------------------------------------------- a camera that stops


class ThreadedCamera:
    """The robot's camera publishing 10 pictures/s from a thread of its own (the test's
    thread runs Playwright's loop), until paused, resumed or closed; ``reconnect`` drops
    the rosbridge connection and opens a new one, as a robot that lost its network."""

    def __init__(self, rosbridge_url: str) -> None:
        self.url = rosbridge_url
        self.publishing = threading.Event()
        self.publishing.set()
        self.reconnecting = threading.Event()
        self.reconnected = threading.Event()
        self.closed = threading.Event()
        self.jpegs = camera_frames(640, 480, quality=80, count=30)
        self.thread = threading.Thread(target=lambda: asyncio.run(self._run()), daemon=True)
        self.thread.start()

    async def _run(self) -> None:
        camera = await Camera.connect(self.url)
        i = 0
        while not self.closed.is_set():
            if self.reconnecting.is_set():
                await camera.close()
                camera = await Camera.connect(self.url)
                self.reconnecting.clear()
                self.reconnected.set()
            if self.publishing.is_set():
                await camera.send(self.jpegs[i % len(self.jpegs)])
                i += 1
            await asyncio.sleep(0.1)
        await camera.close()

    def close(self) -> None:
        self.closed.set()
        self.thread.join(10)


@pytest.fixture
def threaded_camera(demo: Demo) -> Iterator[ThreadedCamera]:
    camera = ThreadedCamera(demo.server.rosbridge_url(demo.tokens[ROBOT]))
    yield camera
    camera.close()


def frames_grow(page: Page, more: int = 5) -> None:
    page.wait_for_function(
        "n => Number(document.getElementById('camera-frame').dataset.frames || 0) >= n",
        arg=presented(page) + more,
        timeout=20_000,
    )


def test_the_panel_shows_a_camera_that_stops_as_stalled_until_it_comes_back(
    context: BrowserContext, demo: Demo, threaded_camera: ThreadedCamera
) -> None:
    wait_for_camera(demo)
    page = open_as(context, demo, "viewer", "/robots/robot_0/")
    frames_grow(page)
    stalled = page.locator("#camera-stalled")
    expect(stalled).to_be_hidden()
    threaded_camera.publishing.clear()  # the camera stops; the robot stays connected
    expect(stalled).to_be_visible(timeout=10_000)
    expect(stalled).to_contain_text("Stalled")
    expect(page.locator("#camera-frame")).to_have_attribute("data-stalled", "true")
    screenshot(page, "robot-camera-stalled")
    threaded_camera.publishing.set()
    frames_grow(page)
    expect(stalled).to_be_hidden(timeout=5_000)
    assert page.get_attribute("#camera-frame", "data-mode") == "webrtc"


def test_the_same_webrtc_stream_resumes_when_the_robot_reconnects(
    context: BrowserContext, demo: Demo, threaded_camera: ThreadedCamera
) -> None:
    wait_for_camera(demo)
    page = open_as(context, demo, "viewer", "/robots/robot_0/")
    frames_grow(page)
    video = page.evaluate_handle(VIDEO)
    threaded_camera.reconnecting.set()
    assert threaded_camera.reconnected.wait(10)
    frames_grow(page, 10)  # pictures the robot sent after it reconnected
    assert page.get_attribute("#camera-frame", "data-mode") == "webrtc"
    assert page.get_attribute("#camera-frame", "data-fallback") is None
    assert page.evaluate(f"v => v === {VIDEO}", video)  # the same player, not a new one


def test_debian_chromium_plays_h264_by_webrtc(
    context: BrowserContext, demo: Demo, stamping_agent: Path
) -> None:
    # Debian's chromium decodes H.264 (its RTCRtpReceiver lists constrained baseline,
    # main and high): the viewer page's codec=h264 plays without falling back to MJPEG.
    wait_for_camera(demo)
    page = open_as(context, demo, "viewer", f"/stream_viewer?topic={TOPIC}&type=webrtc&codec=h264")
    page.wait_for_function("() => window.delayMeter?.count >= 10", timeout=30_000)
    assert page.evaluate("() => document.getElementById('stream').tagName") == "VIDEO"
    streams = video_stats(demo.server.url, demo.tokens[ROBOT])
    assert [s["viewers"] for s in streams if s["type"] == "webrtc/h264"] == [1]
    delays = page.evaluate("() => window.delayMeter.summary()")
    assert 0 < delays["p50"] < GLASS_TO_GLASS_P95_MS
