"""Replay in a real browser: the robot page switches from live to a recording, and the
timeline and the map follow the recording."""

from __future__ import annotations

import base64
import re
import time
from pathlib import Path

import cv2
import numpy as np
import pytest
from playwright.sync_api import BrowserContext, expect

from telemetry.domain import ros1
from telemetry.domain.events import EVENT_TYPE, EventDraft, Kind, Severity, as_log
from telemetry.recording import files
from tests.browser_support import BUILDING, ROBOT, Demo, drawn_robot
from tests.fixtures_live import LiveServer, LiveServers

pytest_plugins = ["tests.browser_support"]
pytestmark = [pytest.mark.browser, pytest.mark.django_db(transaction=True)]

NS = 1_000_000_000
CORRIDOR_A = f"{BUILDING}/CorridorA"
START = int(time.time()) - 600  # ten minutes ago: 20 s of the robot driving along x


def x_at(second: float) -> float:
    return 2.0 + 0.5 * second


@pytest.fixture
def recordings(tmp_path: Path) -> Path:
    root = tmp_path / "recordings"
    writer = files.RotatingFiles(root, ROBOT, max_seconds=3600, max_bytes=2**30)
    pose_type = "geometry_msgs/PoseStamped"
    map_type = "std_msgs/String"
    writer.write(
        files.Record(
            f"/{ROBOT}/map_id",
            map_type,
            ros1.schema_text(map_type).encode(),
            START * NS,
            ros1.encode(map_type, {"data": CORRIDOR_A}),
        )
    )
    for tenth in range(201):
        second = tenth / 10
        msg = {
            "header": {"stamp": {"sec": START, "nanosec": 0}, "frame_id": CORRIDOR_A},
            "pose": {"position": {"x": x_at(second), "y": 23.2}, "orientation": {"w": 1.0}},
        }
        writer.write(
            files.Record(
                f"/{ROBOT}/pose",
                pose_type,
                ros1.schema_text(pose_type).encode(),
                int((START + second) * NS),
                ros1.encode(pose_type, msg),
            )
        )
        if tenth in EVENTS:
            writer.write(event_record(EVENTS[tenth], START + second))
        if tenth in FRAMES:
            writer.write(frame_record(START + second, FRAMES[tenth]))
        if tenth % 10 == 0:
            writer.write(odom_record(START + second))
    writer.close()
    return root


# camera frames recorded (the building records the camera at 1/6 Hz): tenth -> grey level
FRAMES = {20: 40, 80: 120, 140: 200}


def frame_record(at: float, grey: int) -> files.Record:
    ok, jpeg = cv2.imencode(".jpg", np.full((48, 64, 3), grey, np.uint8))
    assert ok
    image_type = "sensor_msgs/CompressedImage"
    msg = {
        "header": {"stamp": {"sec": int(at), "nanosec": 0}, "frame_id": "camera"},
        "format": "jpeg",
        "data": base64.b64encode(jpeg.tobytes()).decode(),
    }
    return files.Record(
        f"/{ROBOT}/camera/image/compressed",
        image_type,
        ros1.schema_text(image_type).encode(),
        int(at * NS),
        ros1.encode(image_type, msg),
    )


def odom_record(at: float) -> files.Record:
    odom_type = "nav_msgs/Odometry"
    msg = {
        "header": {"stamp": {"sec": int(at), "nanosec": 0}, "frame_id": "odom"},
        "twist": {"twist": {"linear": {"x": 0.5}, "angular": {"z": 0.0}}},
    }
    return files.Record(
        f"/{ROBOT}/odom",
        odom_type,
        ros1.schema_text(odom_type).encode(),
        int(at * NS),
        ros1.encode(odom_type, msg),
    )


def plotted_until(page) -> float | None:
    """The time of the velocity plots' newest sample."""
    return page.evaluate("() => window.cloudnav.robotPage.plots.linear.newest()")


def shown_frame(page) -> tuple[int, int] | None:
    """The stamp (seconds) and the decoded grey level of the camera frame on show."""
    return page.evaluate(
        """() => {
          const img = document.getElementById("camera-replay");
          if (!img.complete || !img.naturalWidth || !img.dataset.stamp) return null;
          const canvas = document.createElement("canvas");
          canvas.width = img.naturalWidth; canvas.height = img.naturalHeight;
          const g = canvas.getContext("2d");
          g.drawImage(img, 0, 0);
          return [Number(img.dataset.stamp), g.getImageData(5, 5, 1, 1).data[0]];
        }"""
    )


def wait_for_frame(page, stamp: int) -> int:
    deadline = time.monotonic() + 10
    while time.monotonic() < deadline:
        found = shown_frame(page)
        if found is not None and found[0] == stamp:
            return found[1]
        page.wait_for_timeout(50)
    raise AssertionError(f"the frame of {stamp} was not shown; on show: {shown_frame(page)}")


# events the server derived while recording, by the tenth of a second they happened at
EVENTS = {
    50: (Kind.CONNECTED, Severity.INFO, f"{ROBOT} connected"),
    150: (Kind.GOAL_ABORTED, Severity.ERROR, f"{ROBOT}: goal aborted: no path"),
}


def event_record(event: tuple[Kind, Severity, str], at: float) -> files.Record:
    kind, severity, message = event
    draft = EventDraft(at, kind, severity, ROBOT, message)
    return files.Record(
        f"/{ROBOT}/events",
        EVENT_TYPE,
        ros1.schema_text(EVENT_TYPE).encode(),
        int(at * NS),
        ros1.encode(EVENT_TYPE, as_log(draft)),
    )


@pytest.fixture
def daphne_server(daphne_servers: LiveServers, recordings: Path) -> LiveServer:
    return daphne_servers.start(env={"CLOUDNAV_RECORDING_DIR": str(recordings)})


def test_the_robot_page_replays_a_recording_with_its_timeline(
    context: BrowserContext, demo: Demo
) -> None:
    # no robot is live, so the camera's stream never sends a first frame: do not wait for
    # the page's load event, only for its scripts
    name, value = demo.cookies["viewer"]
    context.add_cookies([{"name": name, "value": value, "url": demo.server.url}])
    page = context.new_page()
    page.goto(demo.url(f"/robots/{ROBOT}/"), wait_until="domcontentloaded")
    page.wait_for_function("() => window.cloudnav?.robotPage?.replay")
    page.click("#replay-toggle")
    expect(page.locator("#replay-bar")).to_be_visible()
    expect(page.locator("#replay-time")).to_have_attribute("min", str(START))
    expect(page.locator("#replay-time")).to_have_attribute("max", str(START + 20))
    expect(page.locator("#map-wrap")).to_have_attribute("data-robot", f"{x_at(0):.3f},23.200")
    # the robot's events are marks on the timeline, coloured by severity
    marks = page.locator("#replay-marks .replay-mark")
    expect(marks).to_have_count(2)
    expect(marks.nth(0)).to_have_attribute("data-kind", "robot_connected")
    expect(marks.nth(0)).to_have_class("replay-mark info")
    aborted = marks.nth(1)
    expect(aborted).to_have_attribute("data-kind", "goal_aborted")
    expect(aborted).to_have_class("replay-mark error")
    expect(aborted).to_have_attribute(
        "title", re.compile(rf"goal_aborted: {ROBOT}: goal aborted: no path$")
    )
    # a click on a mark seeks to its event: the map shows where the robot was then
    aborted.click()
    expect(page.locator("#map-wrap")).to_have_attribute("data-robot", f"{x_at(15):.3f},23.200")
    assert float(page.locator("#replay-time").input_value()) == pytest.approx(START + 15)
    # the camera card shows the last frame recorded before that point, instead of live video
    expect(page.locator("#camera-replay")).to_be_visible()
    expect(page.locator("#camera-frame")).to_be_hidden()
    assert abs(wait_for_frame(page, START + 14) - 200) <= 8
    # seek to the middle: the map shows where the robot was then
    page.eval_on_selector(
        "#replay-time",
        "(el, t) => { el.value = String(t); el.dispatchEvent(new Event('input')); }",
        START + 10,
    )
    expect(page.locator("#map-wrap")).to_have_attribute("data-robot", f"{x_at(10):.3f},23.200")
    expect(page.locator("#map-wrap")).to_have_attribute("data-loaded", CORRIDOR_A)
    assert abs(wait_for_frame(page, START + 8) - 120) <= 8
    # the velocity plots run on the recording's clock, cleared on a seek
    assert plotted_until(page) == START + 10
    # play at 10x: the robot drives on to where the recording ends
    page.select_option("#replay-speed", "10")
    page.click("#replay-play")
    expect(page.locator("#map-wrap")).to_have_attribute(
        "data-robot", f"{x_at(20):.3f},23.200", timeout=15_000
    )
    where = drawn_robot(page)
    assert where is not None
    assert where[0] == pytest.approx(x_at(20))
    expect(page.locator("#replay-play")).to_have_text("Play")
    # and back to live
    assert wait_for_frame(page, START + 14)  # the last frame, played through
    assert plotted_until(page) == START + 20
    page.click("#replay-toggle")
    expect(page.locator("#replay-bar")).to_be_hidden()
    expect(page.locator("#camera-frame")).to_be_visible()
    assert plotted_until(page) is None  # back to live: the recording's samples are gone


def test_replaying_says_so_in_the_header_and_disarms_teleop(
    context: BrowserContext, demo: Demo
) -> None:
    name, value = demo.cookies["operator"]
    context.add_cookies([{"name": name, "value": value, "url": demo.server.url}])
    page = context.new_page()
    page.goto(demo.url(f"/robots/{ROBOT}/"), wait_until="domcontentloaded")
    header = page.locator("#conn-state")
    expect(header).to_have_text("Live")
    page.click("#lock-acquire")
    expect(page.locator("#lock-state")).to_have_text("You are driving")
    page.click("#replay-toggle")
    expect(page.locator("#replay-bar")).to_be_visible()
    # the header says what is on show, and the recording drives nothing
    expect(header).to_have_text("Replay")
    expect(page.locator("#lock-state")).to_have_text("Not driving")
    expect(page.locator("#lock-acquire")).to_be_disabled()
    expect(page.locator("#lock-message")).to_contain_text("Replaying a recording")
    # back to live: live again, and control may be taken again
    page.click("#replay-toggle")
    expect(header).to_have_text("Live")
    expect(page.locator("#lock-acquire")).to_be_enabled()
    page.click("#lock-acquire")
    expect(page.locator("#lock-state")).to_have_text("You are driving")
