"""Mapping in a real browser: an admin starts a session on the robot page, watches the
map appear and grow with the robot's corrected path, finishes and publishes it as a new
sub-map; and edits a proposed change cell by cell (mouse and touch, undo) before
accepting it, the published version holding the cells painted."""

from __future__ import annotations

import base64
import io
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
from PIL import Image as PILImage
from playwright.sync_api import Browser, BrowserContext, Page, Request, expect

from maps import services
from maps.domain.demo_building import demo_building
from maps.models import ChangeProposal, SubMap
from tests.browser_support import (
    ACTION_TIMEOUT_MS,
    BUILDING,
    PHONE,
    ROBOT,
    Demo,
    open_as,
    pinch,
    screenshot,
    swipe,
    world_to_page,
)
from tests.fixtures_live import agent_process

pytest_plugins = ["tests.browser_support"]
pytestmark = [pytest.mark.browser, pytest.mark.django_db(transaction=True)]


@pytest.fixture
def robot_at_the_entrance(demo: Demo, tmp_path: Path):
    """``robot_0`` where it reads the entrance tag at once (it localises in Corridor A)."""
    start = ",".join(str(v) for v in demo_building().robot_starts[0])
    with agent_process(
        demo.server.url, demo.tokens[ROBOT], tmp_path / "agent.log", "--start", start
    ) as log:
        yield log


def test_an_admin_maps_with_a_robot_watches_the_map_grow_and_publishes_it(
    robot_at_the_entrance: Path, context: BrowserContext, demo: Demo
) -> None:
    page = open_as(context, demo, "admin", f"/robots/{ROBOT}/")
    expect(page.locator("#robot-map")).to_contain_text("CorridorA", timeout=30_000)
    asked = sessions_asked(page)
    page.fill("#mapping-start input[name=code]", "Porch")
    page.click("#mapping-start button[type=submit]")
    expect(page.locator("#mapping-state")).to_have_text(f"{BUILDING}/Porch: running")
    page.wait_for_function(
        "() => Number(document.getElementById('mapping-wrap').dataset.snapshot || 0) >= 1",
        timeout=30_000,
    )
    first = int(page.get_attribute("#mapping-wrap", "data-snapshot") or 0)
    page.wait_for_function(
        f"() => Number(document.getElementById('mapping-wrap').dataset.snapshot) > {first}",
        timeout=30_000,
    )
    expect(page.locator("#mapping-figures")).to_contain_text("keyframes")
    screenshot(page, "robot-mapping-live")
    # Told as the map was saved: three reads within 10 s, which neither the start's own
    # read nor the 30 s fallback make.
    assert any(later - earlier <= 10 for earlier, later in zip(asked, asked[2:], strict=False))

    page.click("#mapping-finish")
    expect(page.locator("#mapping-state")).to_have_text(f"{BUILDING}/Porch: finished")
    page.click("#mapping-publish")  # asked first, with a note for the version's history
    dialog = page.locator("#mapping-publish-dialog")
    expect(dialog).to_contain_text(f"Publish {BUILDING}/Porch?")
    dialog.locator("textarea[name=note]").fill("the porch, mapped by robot_0")
    dialog.locator("button[value=confirm]").click()
    expect(page.locator("#mapping-messages")).to_contain_text("Published as v1")
    versions = page.request.get(demo.url(f"/api/buildings/{BUILDING}/maps/Porch/versions/"))
    assert versions.ok
    assert versions.json()["versions"][0]["reason"] == "mapping"
    assert versions.json()["versions"][0]["note"] == "the porch, mapped by robot_0"


@pytest.fixture
def camera_only_robot(demo: Demo, tmp_path: Path):
    """``robot_0`` with an RGB-D camera and no laser, depth with every frame, in Corridor A
    facing its textured length."""
    options = ("--sensors", "rgbd", "--depth-rate", "5", "--no-visual", "--start", "5,23,0")
    with agent_process(
        demo.server.url, demo.tokens[ROBOT], tmp_path / "agent.log", *options
    ) as log:
        yield log


def test_an_admin_starts_a_visual_session_and_sees_its_figures_and_its_3d_map(
    camera_only_robot: Path, context: BrowserContext, phone: BrowserContext, demo: Demo
) -> None:
    page = open_as(context, demo, "admin", f"/robots/{ROBOT}/")
    give_up = time.monotonic() + 60
    while not robot_online(page, demo):  # it has no map to show: asked of the fleet
        assert time.monotonic() < give_up, "the robot never came online"
        page.wait_for_timeout(250)
    page.fill("#mapping-start input[name=code]", "Lobby")
    page.select_option("#mapping-start select[name=kind]", "visual")
    page.click("#mapping-start button[type=submit]")
    expect(page.locator("#mapping-state")).to_have_text(f"{BUILDING}/Lobby: running")
    figures = page.locator("#mapping-figures")
    expect(figures).to_contain_text("0 frames lost", timeout=60_000)  # mapped from the camera
    expect(figures).to_contain_text("1 keyframes")
    expect(figures).to_contain_text("0 restarts from odometry")
    sessions = page.request.get(demo.url(f"/api/mapping/sessions/?robot={ROBOT}"))
    assert sessions.json()[0]["kind"] == "visual"

    # The 3D view beside the grid draws the keyframe's points (WebGL: SwiftShader).
    expect(page.locator("#mapping-3d-wrap")).to_be_visible()
    page.wait_for_function(
        "() => Number(document.getElementById('mapping-3d').dataset.points) > 500",
        timeout=60_000,
    )
    before = canvas_pixels(page, "#mapping-3d")
    assert grey_pixels(before) > 200  # the camera's grey walls as points, not a blank view
    page.locator("#mapping-3d").scroll_into_view_if_needed()
    box = page.locator("#mapping-3d").bounding_box()
    assert box is not None
    turned = view_of(page)[0]
    page.mouse.move(box["x"] + box["width"] / 2, box["y"] + box["height"] / 2)
    page.mouse.down()
    page.mouse.move(box["x"] + box["width"] / 2 + 120, box["y"] + box["height"] / 2, steps=8)
    page.mouse.up()  # OrbitControls turn the view
    assert abs(view_of(page)[0] - turned) > 0.1  # radians
    after = canvas_pixels(page, "#mapping-3d")
    assert (after != before).any(axis=2).mean() > 0.01
    screenshot(page, "robot-mapping-visual-3d")

    # On a phone: the view fits the screen, one finger turns it and two zoom it.
    small = open_as(phone, demo, "admin", f"/robots/{ROBOT}/")
    small.wait_for_function(
        "() => Number(document.getElementById('mapping-3d').dataset.points) > 500",
        timeout=60_000,
    )
    small.locator("#mapping-3d").scroll_into_view_if_needed()
    box = small.locator("#mapping-3d").bounding_box()
    assert box is not None
    assert 0 <= box["x"] <= box["x"] + box["width"] <= PHONE["width"]
    assert small.evaluate("document.documentElement.scrollWidth") <= PHONE["width"]
    turned, away = view_of(small)
    swipe(small, "#mapping-3d", 120)
    assert abs(view_of(small)[0] - turned) > 0.1  # radians
    pinch(small, "#mapping-3d")
    assert view_of(small)[1] < 0.9 * away  # fingers apart: closer
    screenshot(small, "robot-mapping-visual-3d-phone")

    # Driven down the corridor by teleop: the camera's path joins the keyframes, and the
    # view draws as many loop closures as the session made. (Forward, not on the spot:
    # keyframes turned on the spot stand at one point, a path no pixel shows.)
    drive_until_keyframes(page, 4)
    page.reload()  # looked at afresh: from behind the first keyframe, the path ahead
    page.wait_for_function(
        "() => Number(document.getElementById('mapping-3d').dataset.keyframes) >= 4",
        timeout=60_000,
    )
    view = page.locator("#mapping-3d")
    keyframes = int(view.get_attribute("data-keyframes") or "0")
    assert int(view.get_attribute("data-path-points") or "0") == keyframes
    stats = page.request.get(demo.url(f"/api/mapping/sessions/?robot={ROBOT}")).json()[0]["stats"]
    assert stats["keyframes"] >= keyframes
    assert int(view.get_attribute("data-loops") or "-1") == stats.get("loop_closures", 0)
    assert coloured_pixels(canvas_pixels(page, "#mapping-3d"), PATH_COLOUR) > 20
    screenshot(page, "robot-mapping-visual-3d-path")


PATH_COLOUR = (0x4F, 0xC3, 0xF7)
"""The camera's path in the 3D view (static/js/map3d.js)."""


def drive_until_keyframes(page: Page, keyframes: int) -> None:
    """Take the lock and hold the forward key, slowly, until the 3D view shows
    ``keyframes``; then let go."""
    page.click("#lock-acquire")
    expect(page.locator("#lock-state")).to_have_text("You are driving")
    page.locator("#max-linear").fill("0.2")  # the camera tracks a walk at 5 frames/s
    page.evaluate("document.activeElement.blur()")  # keys drive only when not typing
    page.keyboard.down("ArrowUp")
    page.wait_for_function(
        f"() => Number(document.getElementById('mapping-3d').dataset.keyframes) >= {keyframes}",
        timeout=90_000,
    )
    page.keyboard.up("ArrowUp")
    expect(page.locator("#odom-speed")).to_have_text("0.00 m/s", timeout=10_000)


def coloured_pixels(pixels: np.ndarray, colour: tuple[int, int, int]) -> int:
    """Pixels within 3 of ``colour`` in each channel."""
    return int((np.abs(pixels.astype(int) - np.array(colour)) <= 3).all(axis=2).sum())


def view_of(page: Page) -> tuple[float, float]:
    """Where the 3D view looks from: turned (radians about the map's z) and how far."""
    view = page.locator("#mapping-3d")
    return float(view.get_attribute("data-azimuth") or "nan"), float(
        view.get_attribute("data-distance") or "nan"
    )


def canvas_pixels(page: Page, selector: str) -> np.ndarray:
    """The RGB pixels a canvas shows (its PNG, as the page reads it)."""
    url = page.eval_on_selector(selector, "(canvas) => canvas.toDataURL('image/png')")
    png = base64.b64decode(url.split(",", 1)[1])
    return np.asarray(PILImage.open(io.BytesIO(png)).convert("RGB"))


def grey_pixels(pixels: np.ndarray) -> int:
    """Pixels of a grey (r = g = b) not near black: the simulated camera's colours, which
    neither the view's background nor its floor grid has."""
    r, g, b = (pixels[..., channel].astype(int) for channel in range(3))
    return int(((r == g) & (g == b) & (r > 40)).sum())


def robot_online(page: Page, demo: Demo) -> bool:
    fleet = page.request.get(demo.url("/api/fleet/")).json()
    return any(entry["robot"] == ROBOT and entry["online"] for entry in fleet)


def sessions_asked(page: Page) -> list[float]:
    """When (monotonic seconds) ``page`` asks for the robot's mapping sessions from now on."""
    asked: list[float] = []

    def seen(request: Request) -> None:
        if "/api/mapping/sessions/?" in request.url:
            asked.append(time.monotonic())

    page.on("request", seen)
    return asked


def test_an_idle_robot_page_is_told_of_mapping_sessions_and_does_not_poll(
    context: BrowserContext, demo: Demo
) -> None:
    page = open_as(context, demo, "operator", f"/robots/{ROBOT}/")
    expect(page.locator("#mapping-state")).to_have_text("no session")
    asked = sessions_asked(page)
    page.wait_for_timeout(IDLE_WINDOW_MS)
    assert asked == []


IDLE_WINDOW_MS = 8000


@dataclass
class Corridor:
    """Corridor A with an open proposal (a 2 x 2 cabinet) on version 1, and a block of
    free cells to paint in: ``block`` is its bottom-left cell (row, col)."""

    proposal: int
    cabinet: list[list[int]]
    block: tuple[int, int]
    origin: tuple[float, float]
    resolution: float
    width: int


def free_block(grid: np.ndarray, size: int, away_from: tuple[int, int]) -> tuple[int, int]:
    """The bottom-left cell of a free ``size`` x ``size`` block at least 6 cells from
    ``away_from``."""
    rows, cols = grid.shape
    for row in range(rows - size):
        for col in range(cols - size):
            far = max(abs(row - away_from[0]), abs(col - away_from[1])) > size + 6
            if far and not grid[row : row + size, col : col + size].any():
                return row, col
    raise AssertionError("Corridor A has no free block")


@pytest.fixture
def corridor_with_a_proposal(demo: Demo) -> Corridor:
    """Stored before Chromium starts (the ORM is not used inside Playwright's loop)."""
    corridor = SubMap.objects.get(building__code=BUILDING, code="CorridorA")
    grid = services.grid_of(corridor)
    middle = (corridor.height // 2, corridor.width // 2)
    cabinet = [[middle[0] + r, middle[1] + c] for r in range(2) for c in range(2)]
    made = ChangeProposal.objects.create(
        submap=corridor, based_on=1, added=cabinet, added_passes=[2] * 4, passes=2, scans=80
    )
    return Corridor(
        made.pk,
        cabinet,
        free_block(grid, 8, middle),
        (corridor.origin_x, corridor.origin_y),
        corridor.resolution,
        corridor.width,
    )


@pytest.fixture
def touch_context(browser: Browser) -> Iterator[BrowserContext]:
    opened = browser.new_context(viewport={"width": 1280, "height": 900}, has_touch=True)
    opened.set_default_timeout(ACTION_TIMEOUT_MS)
    yield opened
    opened.close()


def cell_on_page(page: Page, corridor: Corridor, row: int, col: int) -> tuple[float, float]:
    x = corridor.origin[0] + (col + 0.5) * corridor.resolution
    y = corridor.origin[1] + (row + 0.5) * corridor.resolution
    return world_to_page(page, "#map-canvas", x, y)


def mouse_stroke(page: Page, cells: list[tuple[float, float]]) -> None:
    page.mouse.move(*cells[0])
    page.mouse.down()
    for at in cells[1:]:
        page.mouse.move(*at, steps=3)
    page.mouse.up()


def touch_stroke(page: Page, cells: list[tuple[float, float]]) -> None:
    """One finger down on the first point, moving through the others, lifted."""
    cdp = page.context.new_cdp_session(page)
    first, *rest = cells
    cdp.send(
        "Input.dispatchTouchEvent",
        {"type": "touchStart", "touchPoints": [{"x": first[0], "y": first[1], "id": 1}]},
    )
    for x, y in rest:
        cdp.send(
            "Input.dispatchTouchEvent",
            {"type": "touchMove", "touchPoints": [{"x": x, "y": y, "id": 1}]},
        )
        page.wait_for_timeout(30)  # a finger moves over frames
    cdp.send("Input.dispatchTouchEvent", {"type": "touchEnd", "touchPoints": []})


def test_an_admin_edits_a_proposal_cell_by_cell_and_the_published_version_has_the_cells(
    corridor_with_a_proposal: Corridor, touch_context: BrowserContext, demo: Demo
) -> None:
    corridor = corridor_with_a_proposal
    page = open_as(touch_context, demo, "admin", f"/buildings/{BUILDING}/maps/CorridorA/")
    row = page.locator(f"#changes-list tr[data-proposal='{corridor.proposal}']")
    expect(row).to_contain_text("4 cells became occupied, 0 free")
    row.locator("button", has_text="Edit").click()
    expect(page.locator("#change-editor")).to_be_visible()
    expect(page.locator("#change-edit-count")).to_contain_text("4 occupied, 0 free, 0 unknown")
    r0, c0 = corridor.block
    x = corridor.origin[0] + (c0 + 4) * corridor.resolution
    y = corridor.origin[1] + (r0 + 4) * corridor.resolution
    page.evaluate(  # zoom in on the block, as a wheel or a pinch would: cells 12 px wide
        "([x, y, px]) => { const v = window.cloudnav.submapPage.view;"
        " v.centerOn({x, y}); v.zoom(px / v.view.scale); }",
        [x, y, 12 / corridor.resolution],
    )

    def cells(r: int, cols: range) -> list[tuple[float, float]]:
        return [cell_on_page(page, corridor, r0 + r, c0 + c) for c in cols]

    def choose(brush: str) -> None:
        page.click(f"#change-editor [data-brush={brush}]")
        page.locator("#map-canvas").scroll_into_view_if_needed()  # the panel scrolled

    mouse_stroke(page, cells(0, range(0, 6)))  # occupied, with the mouse
    touch_stroke(page, cells(3, range(0, 6)))  # occupied, with a finger
    expect(page.locator("#change-edit-count")).to_contain_text("16 occupied")
    mouse_stroke(page, cells(5, range(0, 6)))  # a stroke taken back
    expect(page.locator("#change-edit-count")).to_contain_text("22 occupied")
    page.click("#change-undo")
    page.locator("#map-canvas").scroll_into_view_if_needed()
    expect(page.locator("#change-edit-count")).to_contain_text("16 occupied")
    choose("unknown")
    mouse_stroke(page, cells(6, range(0, 1)))
    choose("free")
    touch_stroke(page, cells(0, range(5, 6)))  # the mouse stroke's last cell, freed
    expect(page.locator("#change-edit-count")).to_contain_text("15 occupied, 1 free, 1 unknown")
    choose("keep")
    cabinet = corridor.cabinet[0]
    page.evaluate(
        "([x, y]) => window.cloudnav.submapPage.view.centerOn({x, y})",
        [
            corridor.origin[0] + (cabinet[1] + 0.5) * corridor.resolution,
            corridor.origin[1] + (cabinet[0] + 0.5) * corridor.resolution,
        ],
    )
    mouse_stroke(page, [cell_on_page(page, corridor, cabinet[0], cabinet[1])])
    expect(page.locator("#change-edit-count")).to_contain_text("14 occupied, 1 free, 1 unknown")
    screenshot(page, "submap-proposal-edit")
    page.click("#change-save")
    expect(page.locator("#change-editor")).to_be_hidden()
    expect(row).to_contain_text("14 cells became occupied, 1 free, 1 unknown (edited)")

    row.locator("button", has_text="Accept").click()
    page.locator("#accept-dialog button[value=confirm]").click()
    expect(page.locator("#versions-current")).to_have_text("v2")
    published = page.request.get(
        demo.url(f"/api/buildings/{BUILDING}/maps/CorridorA/versions/2/grid")
    )
    assert published.ok
    data = published.json()["data"]

    def at(r: int, c: int) -> int:
        return int(data[r * corridor.width + c])

    assert [at(r0, c0 + c) for c in range(6)] == [100] * 5 + [0]
    assert [at(r0 + 3, c0 + c) for c in range(6)] == [100] * 6
    assert [at(r0 + 5, c0 + c) for c in range(6)] == [0] * 6  # the stroke undone
    assert at(r0 + 6, c0) == -1
    assert at(*cabinet) == 0  # kept as in version 1
    assert all(at(r, c) == 100 for r, c in corridor.cabinet[1:])


def test_the_submap_page_keeps_its_cards_apart_and_a_refused_accept_is_said_in_its_card(
    corridor_with_a_proposal: Corridor, sized: BrowserContext, demo: Demo
) -> None:
    corridor = corridor_with_a_proposal
    path = f"/buildings/{BUILDING}/maps/CorridorA/"
    page = open_as(sized, demo, "admin", path)
    row = page.locator(f"#changes-list tr[data-proposal='{corridor.proposal}']")
    expect(row).to_contain_text("4 cells became occupied")
    # Visual map and Metadata are cards of their own, not inside Versions
    assert page.locator("#versions-panel #coverage-panel").count() == 0
    expect(page.locator("#metadata-version")).to_have_text("v1")  # a version is vN here too
    card = page.locator("#changes-panel").bounding_box()
    for name in ("Accept", "Reject"):
        button = row.locator("button", has_text=name).bounding_box()
        assert card is not None
        assert button is not None
        assert card["x"] <= button["x"]
        assert button["x"] + button["width"] <= card["x"] + card["width"]
    width = sized.pages[0].viewport_size["width"]  # type: ignore[index]
    screenshot(page, f"submap-changes-{width}")

    other = sized.new_page()  # another admin's page rejects it meanwhile
    other.goto(demo.url(path))
    other.locator(
        f"#changes-list tr[data-proposal='{corridor.proposal}'] button", has_text="Reject"
    ).click()
    expect(other.locator(f"#changes-list tr[data-proposal='{corridor.proposal}']")).to_have_count(0)
    row.locator("button", has_text="Accept").click()
    page.locator("#accept-dialog button[value=confirm]").click()
    expect(page.locator("#changes-panel .alert.error")).to_contain_text("Not accepted")
    expect(page.locator("#versions-diff")).to_be_hidden()
