"""An admin reviews a sub-map's versions in a real browser: the history, a comparison drawn
over the map, a rollback; a change the fleet proposed, shown over the map and accepted.
The robot driving in that sub-map then says it holds the new version, and its page
shows it."""

from __future__ import annotations

import io
import time
from pathlib import Path

import numpy as np
import pytest
from PIL import Image
from playwright.sync_api import BrowserContext, expect

from maps import services
from maps.domain.demo_building import demo_building
from maps.domain.mapfile import MapMetadata, load_map_upload, map_yaml_text
from maps.models import Building, ChangeProposal, SubMap
from tests.browser_support import BUILDING, ROBOT, Demo, open_as, screenshot
from tests.fixtures_live import agent_process

pytest_plugins = ["tests.browser_support"]
pytestmark = [pytest.mark.browser, pytest.mark.django_db(transaction=True)]

CABINET_CELLS = 6 * 10
ENTERING_DEADLINE = 90.0
"""Seconds for the robot to take the new version: it must come to the tag and read it."""
ACCEPT_TO_ROBOT_S = 10.0


@pytest.fixture
def corridor_with_a_cabinet(demo: Demo) -> None:
    """Version 2 of Corridor A: a cabinet (6 x 10 cells) in the middle of the corridor
    (stored before Chromium starts: the ORM is not used inside Playwright's loop)."""
    corridor = next(s for s in demo_building().submaps if s.code == "CorridorA")
    pixels = np.array(Image.open(io.BytesIO(corridor.pgm)))
    middle_row, middle_col = pixels.shape[0] // 2, pixels.shape[1] // 2
    pixels[middle_row - 3 : middle_row + 3, middle_col - 5 : middle_col + 5] = 0
    out = io.BytesIO()
    Image.fromarray(pixels, "L").save(out, "PPM")
    meta = MapMetadata(
        image="CorridorA.pgm",
        resolution=corridor.resolution,
        origin=corridor.origin,
        occupied_thresh=corridor.occupied_thresh,
        free_thresh=corridor.free_thresh,
        negate=False,
    )
    loaded = load_map_upload(map_yaml_text(meta).encode(), {meta.image: out.getvalue()}, 10**8)
    building = Building.objects.get(code=BUILDING)
    services.save_submap(building, "CorridorA", loaded, replace=True, note="a cabinet moved in")


@pytest.fixture
def robot_in_corridor_a(demo: Demo, tmp_path: Path):
    """``robot_0`` starting where it reads the entrance tag at once: it enters Corridor A."""
    start = ",".join(str(v) for v in demo_building().robot_starts[0])
    with agent_process(
        demo.server.url, demo.tokens[ROBOT], tmp_path / "agent.log", "--start", start
    ) as log:
        yield log


def held_version(demo: Demo, page) -> int | None:
    fleet = page.request.get(demo.url(f"/api/fleet/?building={BUILDING}")).json()
    entry = next(e for e in fleet if e["robot"] == ROBOT)
    return entry["map_version"] if entry["map_id"] == f"{BUILDING}/CorridorA" else None


def test_an_admin_compares_and_rolls_back_and_the_robot_takes_the_new_version(
    corridor_with_a_cabinet: None, robot_in_corridor_a: Path, context: BrowserContext, demo: Demo
) -> None:
    page = open_as(context, demo, "admin", f"/buildings/{BUILDING}/maps/CorridorA/")
    expect(page.locator("#versions-list tr")).to_have_count(2)
    expect(page.locator("#versions-current")).to_have_text("v2")
    expect(page.locator("#versions-list tr[data-version='2']")).to_contain_text("a cabinet")

    page.locator("#versions-list tr[data-version='1'] button", has_text="Compare").click()
    expect(page.locator("#versions-diff")).to_contain_text(f"{CABINET_CELLS} cells became occupied")
    screenshot(page, "submap-versions-compare")

    deadline = time.monotonic() + ENTERING_DEADLINE
    while held_version(demo, page) != 2:
        assert time.monotonic() < deadline, "the robot never entered Corridor A"
        time.sleep(0.2)

    page.locator("#versions-list tr[data-version='1'] button", has_text="Roll back").click()
    page.locator("#rollback-dialog button[value=confirm]").click()
    rolled_back = time.monotonic()
    expect(page.locator("#versions-current")).to_have_text("v3")
    expect(page.locator("#versions-list tr[data-version='3']")).to_contain_text("rollback")
    while held_version(demo, page) != 3:
        assert time.monotonic() - rolled_back < ACCEPT_TO_ROBOT_S, "the robot kept version 2"
        time.sleep(0.2)

    robot = open_as(context, demo, "operator", f"/robots/{ROBOT}/")
    expect(robot.locator("#robot-map")).to_have_text(f"{BUILDING}/CorridorA")
    expect(robot.locator("#robot-map-version")).to_have_text("v3")
    screenshot(robot, "robot-map-version")


@pytest.fixture
def a_proposed_cabinet(demo: Demo) -> int:
    """An open proposal for Corridor A's version 1: a 4 x 4 cell cabinet in the corridor
    (stored before Chromium starts)."""
    corridor = SubMap.objects.get(building__code=BUILDING, code="CorridorA")
    middle_row, middle_col = corridor.height // 2, corridor.width // 2
    cells = [[middle_row + r, middle_col + c] for r in range(4) for c in range(4)]
    made = ChangeProposal.objects.create(
        submap=corridor,
        based_on=1,
        added=cells,
        added_passes=[2] * len(cells),
        added_robots=[2] * len(cells),
        passes=2,
        robots=2,
        scans=240,
    )
    return made.pk


def test_an_admin_accepts_a_proposed_change_and_the_robot_takes_it(
    a_proposed_cabinet: int, robot_in_corridor_a: Path, context: BrowserContext, demo: Demo
) -> None:
    page = open_as(context, demo, "admin", f"/buildings/{BUILDING}/maps/CorridorA/")
    row = page.locator(f"#changes-list tr[data-proposal='{a_proposed_cabinet}']")
    expect(row).to_contain_text("16 cells became occupied, 0 free")
    expect(row).to_contain_text("seen on 2 passes")
    expect(row).to_contain_text("by 2 robots (each cell by at least 2)")
    row.locator("button", has_text="Show").click()
    expect(page.locator("#versions-diff")).to_contain_text("Proposed: 16 cells")
    screenshot(page, "submap-proposed-change")

    deadline = time.monotonic() + ENTERING_DEADLINE
    while held_version(demo, page) != 1:
        assert time.monotonic() < deadline, "the robot never entered Corridor A"
        time.sleep(0.2)
    row.locator("button", has_text="Accept").click()
    page.locator("#accept-dialog button[value=confirm]").click()
    accepted = time.monotonic()
    expect(page.locator("#versions-current")).to_have_text("v2")
    expect(page.locator("#versions-list tr[data-version='2']")).to_contain_text("change")
    expect(page.locator("#changes-list")).to_contain_text("No change proposed.")
    while held_version(demo, page) != 2:
        assert time.monotonic() - accepted < ACCEPT_TO_ROBOT_S, "the robot kept version 1"
        time.sleep(0.2)
