"""A mapping session in a real browser: an admin starts one on the robot page, watches
the map appear and grow with the robot's corrected path, finishes and publishes it as a
new sub-map."""

from __future__ import annotations

from pathlib import Path

import pytest
from playwright.sync_api import BrowserContext, expect

from maps.domain.demo_building import demo_building
from tests.browser_support import BUILDING, ROBOT, Demo, open_as, screenshot
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

    page.click("#mapping-finish")
    expect(page.locator("#mapping-state")).to_have_text(f"{BUILDING}/Porch: finished")
    page.click("#mapping-publish")
    expect(page.locator("#mapping-messages")).to_contain_text("Published as version 1")
    versions = page.request.get(demo.url(f"/api/buildings/{BUILDING}/maps/Porch/versions/"))
    assert versions.ok
    assert versions.json()["versions"][0]["reason"] == "mapping"
