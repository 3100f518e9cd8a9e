"""An admin shaping a building in a real browser: the topology editor and routes, sub-map
upload with its preview, tag placement and printing."""

from __future__ import annotations

import io
import math
import zipfile
from pathlib import Path

import numpy as np
import pytest
from PIL import Image
from playwright.sync_api import BrowserContext, Page, expect

from maps.domain.mapfile import load_map_upload
from tests.browser_support import (
    BUILDING,
    Demo,
    open_as,
    press_and_drag,
    screenshot,
    topology_ids,
    topology_point,
)
from tests.conftest import map_yaml

pytest_plugins = ["tests.browser_support"]
pytestmark = [pytest.mark.browser, pytest.mark.django_db(transaction=True)]


def route_steps(page: Page) -> list[str]:
    return [
        str(code)
        for code in page.locator("#route-steps li").evaluate_all(
            "items => items.map(i => i.dataset.map)"
        )
    ]


def topology_of(page: Page, demo: Demo) -> dict[str, object]:
    answer = page.request.get(demo.url(f"/api/buildings/{BUILDING}/topology"))
    assert answer.ok
    return answer.json()


def save_topology(page: Page) -> None:
    page.click("#topology-save")


def test_an_admin_edits_the_topology_and_sees_the_route_change(
    context: BrowserContext, demo: Demo
) -> None:
    page = open_as(context, demo, "admin", f"/buildings/{BUILDING}/")
    page.select_option("#route-from", "CorridorC")
    page.select_option("#route-to", "Atrium2")
    expect(page.locator("#route-steps li")).to_have_count(2)

    page.mouse.click(*topology_point(page, "topology", "Atrium2↔CorridorC"))
    expect(page.locator("#edge-editor")).to_be_visible()
    page.fill("#edge-cost", "0")
    save_topology(page)
    expect(page.locator("#topology-messages .alert.error")).to_contain_text("positive")

    page.fill("#edge-cost", "20")
    save_topology(page)
    expect(page.locator("#topology-messages .alert.ok")).to_contain_text("saved")
    expect(page.locator("#route-steps li")).to_have_count(3)
    assert route_steps(page) == ["CorridorC", "RoomB", "Atrium2"]
    assert sorted(topology_ids(page, "topology", "node.route")) == [
        "Atrium2",
        "CorridorC",
        "RoomB",
    ]

    page.mouse.click(*topology_point(page, "topology", "CorridorA"))
    page.mouse.click(*topology_point(page, "topology", "Office7"))
    assert "CorridorA↔Office7" in topology_ids(page, "topology", "edge")
    office = topology_point(page, "topology", "Office7")
    page.mouse.move(*office)
    page.mouse.down()
    page.mouse.move(office[0] - 40, office[1] + 60, steps=8)
    page.mouse.up()
    before = {n["code"]: n for n in topology_of(page, demo)["nodes"]}  # type: ignore[attr-defined]
    save_uncrossable_edge(page, demo)
    expect(page.locator("#topology-messages .alert.ok")).to_contain_text("saved")
    expect(page.locator("#topology-validation")).to_contain_text("No tag lets a robot cross")
    page.wait_for_function(
        "window.cloudnav.topologies.topology.cy.getElementById('CorridorA↔Office7').hasClass('invalid')"
    )
    screenshot(page, "building-topology-editor")

    after = {n["code"]: n for n in topology_of(page, demo)["nodes"]}  # type: ignore[attr-defined]
    assert after["Office7"]["x"] < before["Office7"]["x"]
    assert after["Office7"]["y"] < before["Office7"]["y"]
    edges = {(e["a"], e["b"]) for e in topology_of(page, demo)["edges"]}  # type: ignore[attr-defined]
    assert ("CorridorA", "Office7") in edges or ("Office7", "CorridorA") in edges


def save_uncrossable_edge(page: Page, demo: Demo) -> None:
    """Save a graph with the new, untagged edge CorridorA-Office7: warned while editing, asked
    on saving, saved only when confirmed; routes still never use it."""
    warning = page.locator("#topology-validation .alert.warn")
    expect(warning).to_contain_text("Not saved yet")
    expect(warning).to_contain_text("No tag lets a robot cross CorridorA → Office7.")
    page.wait_for_function(
        "window.cloudnav.topologies.topology.cy.getElementById('CorridorA↔Office7').hasClass('invalid')"
    )

    save_topology(page)
    dialog = page.locator("dialog#uncrossable-dialog")
    expect(dialog).to_be_visible()
    expect(dialog.locator("li")).to_have_text(["CorridorA → Office7", "Office7 → CorridorA"])
    screenshot(page, "building-topology-confirm-uncrossable")
    dialog.get_by_role("button", name="Keep editing").click()
    expect(page.locator("#topology-messages")).to_contain_text("Not saved")
    edges = {(e["a"], e["b"]) for e in topology_of(page, demo)["edges"]}  # type: ignore[attr-defined]
    assert ("CorridorA", "Office7") not in edges

    save_topology(page)
    page.locator("dialog#uncrossable-dialog").get_by_role("button", name="Save anyway").click()
    expect(page.locator("#topology-messages .alert.ok")).to_contain_text("saved")
    page.select_option("#route-from", "CorridorA")
    page.select_option("#route-to", "Office7")
    # Routes still go by the tags: round by Room B (Corridor C to Atrium 2 now costs 20).
    expect(page.locator("#route-steps li")).to_have_count(9)
    assert route_steps(page)[:2] == ["CorridorA", "Atrium1"]


def rgba_map() -> bytes:
    """A colour PNG with see-through pixels: the boundary cases of the conversion rule."""
    rng = np.random.default_rng(7)
    pixels = rng.integers(0, 256, (48, 64, 4), dtype=np.uint8)
    pixels[..., 3] = np.where(rng.random((48, 64)) < 0.1, rng.integers(0, 255, (48, 64)), 255)
    out = io.BytesIO()
    Image.fromarray(pixels, "RGBA").save(out, "PNG")
    return out.getvalue()


def test_an_admin_previews_a_submap_before_storing_it(
    context: BrowserContext, demo: Demo, tmp_path: Path
) -> None:
    image, yaml = rgba_map(), map_yaml(image="lab.png", mode="scale", origin=[1.0, 2.0, 0.0])
    (tmp_path / "lab.png").write_bytes(image)
    (tmp_path / "lab.yaml").write_bytes(yaml)
    grid = load_map_upload(yaml, {"lab.png": image}, 10**6).grid
    expected = {
        "free": int((grid == 0).sum()),
        "occupied": int((grid == 100).sum()),
        "unknown": int((grid == -1).sum()),
        "other": int(((grid > 0) & (grid < 100)).sum()),
    }

    page = open_as(context, demo, "admin", f"/buildings/{BUILDING}/upload/")
    page.fill("input[name=code]", "Lab")
    page.fill("input[name=name]", "Laboratory")
    page.set_input_files("input[name=image]", str(tmp_path / "lab.png"))
    page.set_input_files("input[name=yaml]", str(tmp_path / "lab.yaml"))
    counts = page.locator("#preview-counts")
    expect(counts).to_have_attribute("data-free", str(expected["free"]))
    for kind, count in expected.items():
        assert counts.get_attribute(f"data-{kind}") == str(count), kind
    expect(page.locator("#preview-size")).to_contain_text("64\N{MULTIPLICATION SIGN}48 cells")
    assert page.request.get(demo.url(f"/api/buildings/{BUILDING}/maps/Lab/")).status == 404
    screenshot(page, "upload-preview")

    with zipfile.ZipFile(tmp_path / "lab.zip", "w", zipfile.ZIP_DEFLATED) as archive:
        archive.writestr("lab/lab.yaml", yaml)
        archive.writestr("lab/lab.png", image)
    page.click("#upload-kind button[data-kind=archive]")
    page.evaluate("document.getElementById('preview-counts').removeAttribute('data-free')")
    page.set_input_files("input[name=archive]", str(tmp_path / "lab.zip"))
    expect(counts).to_have_attribute("data-free", str(expected["free"]))
    assert counts.get_attribute("data-other") == str(expected["other"])
    page.click("#upload-kind button[data-kind=pair]")

    page.click("#upload-submit")
    expect(page.locator("#upload-messages .alert.ok")).to_contain_text(f"{BUILDING}/Lab")
    page.click("#stored-link")
    expect(page.locator("#map-wrap")).to_have_attribute("data-loaded", "Lab")
    stored = page.request.get(demo.url(f"/api/buildings/{BUILDING}/maps/Lab/grid")).json()
    assert stored["data"] == np.ascontiguousarray(grid).reshape(-1).tolist()


def expected_counts(yaml: bytes, name: str, image: bytes) -> dict[str, int]:
    grid = load_map_upload(yaml, {name: image}, 10**6).grid
    return {
        "free": int((grid == 0).sum()),
        "occupied": int((grid == 100).sum()),
        "unknown": int((grid == -1).sum()),
        "other": int(((grid > 0) & (grid < 100)).sum()),
    }


def test_an_admin_sees_the_servers_preview_and_is_asked_before_replacing_a_map(
    context: BrowserContext, demo: Demo, tmp_path: Path
) -> None:
    """A TIFF (no browser decodes it) under the code of a live sub-map: the server's dry
    run draws it and names a bad field; storing asks first, and only a yes replaces."""
    pixels = Image.open(io.BytesIO(rgba_map())).convert("L")
    (tmp_path / "lab.tif").write_bytes(encode_tiff(pixels))
    (tmp_path / "bad.yaml").write_bytes(map_yaml(image="lab.tif", resolution=-1))
    (tmp_path / "lab.yaml").write_bytes(map_yaml(image="lab.tif"))
    grid_url = demo.url(f"/api/buildings/{BUILDING}/maps/CorridorC/grid")
    page = open_as(context, demo, "admin", f"/buildings/{BUILDING}/upload/")
    live = page.request.get(grid_url).json()["info"]

    page.fill("input[name=code]", "CorridorC")
    page.set_input_files("input[name=image]", str(tmp_path / "lab.tif"))
    page.set_input_files("input[name=yaml]", str(tmp_path / "bad.yaml"))
    expect(page.locator("#upload-messages .alert.error")).to_contain_text("resolution")
    page.set_input_files("input[name=yaml]", str(tmp_path / "lab.yaml"))
    counts = page.locator("#preview-counts")
    expected = expected_counts((tmp_path / "lab.yaml").read_bytes(), "lab.tif", encode_tiff(pixels))
    expect(counts).to_have_attribute("data-free", str(expected["free"]))
    for kind, count in expected.items():
        assert counts.get_attribute(f"data-{kind}") == str(count), kind
    expect(page.locator("#upload-messages .alert.warn")).to_contain_text(
        f"{BUILDING}/CorridorC exists"
    )
    assert "null" not in (counts.text_content() or "")
    screenshot(page, "upload-preview-replaces")

    page.click("#upload-submit")
    dialog = page.locator("dialog#replace-dialog")
    expect(dialog).to_contain_text(f"{BUILDING}/CorridorC already exists")
    screenshot(page, "upload-confirm-replace")
    dialog.get_by_role("button", name="Keep the stored map").click()
    expect(page.locator("#upload-messages .alert.info")).to_contain_text("Not stored")
    assert page.request.get(grid_url).json()["info"]["width"] == live["width"]

    page.click("#upload-submit")
    page.locator("dialog#replace-dialog").get_by_role("button", name="Replace it").click()
    expect(page.locator("#upload-messages .alert.ok")).to_contain_text(f"{BUILDING}/CorridorC")
    assert page.request.get(grid_url).json()["info"]["width"] == 64


def encode_tiff(image: Image.Image) -> bytes:
    out = io.BytesIO()
    image.save(out, "TIFF")
    return out.getvalue()


def test_an_admin_places_a_tag_and_prints_it(context: BrowserContext, demo: Demo) -> None:
    page = open_as(context, demo, "admin", f"/buildings/{BUILDING}/maps/CorridorC/")
    expect(page.locator("#map-wrap")).to_have_attribute("data-loaded", "CorridorC")
    expect(page.locator("#tag-list tr")).to_have_count(4)
    page.click("#place-tag")
    press_and_drag(page, 30.0, 7.5, math.pi / 2)
    assert abs(float(page.input_value("input[name=x]")) - 30.0) < 0.05
    assert abs(float(page.input_value("input[name=yaw_deg]")) - 90.0) < 3.0
    page.select_option("select[name=links_to]", "RoomB")
    page.click("#tag-save")
    expect(page.locator("#tag-messages .alert.ok")).to_contain_text("saved")
    expect(page.locator("#tag-list tr")).to_have_count(5)
    screenshot(page, "submap-tag-editor")

    tags = page.request.get(demo.url(f"/api/tags/?building={BUILDING}&map=CorridorC")).json()
    placed = next(tag for tag in tags if tag["marker_id"] == 21)
    assert placed["links_to"] == "RoomB"
    assert abs(placed["x"] - 30.0) < 0.05
    assert abs(placed["y"] - 7.5) < 0.05
    assert abs(placed["yaw"] - math.pi / 2) < 0.05

    png = page.request.get(demo.url(page.get_attribute("#tag-png", "href") or ""))
    assert png.ok
    assert png.headers["content-type"] == "image/png"
    page.goto(demo.url(f"/buildings/{BUILDING}/"))
    sheet = page.request.get(demo.url(page.get_attribute("#print-sheet", "href") or ""))
    assert sheet.ok
    assert sheet.headers["content-type"] == "application/pdf"
    screenshot(page, "building-page")


def test_a_tag_placed_by_a_click_saves_with_the_millimetres_the_click_gave(
    context: BrowserContext, demo: Demo
) -> None:
    page = open_as(context, demo, "admin", f"/buildings/{BUILDING}/maps/CorridorC/")
    expect(page.locator("#map-wrap")).to_have_attribute("data-loaded", "CorridorC")
    expect(page.locator("#tag-list tr")).to_have_count(4)
    page.click("#place-tag")
    press_and_drag(page, 30.0, 7.5, math.pi / 2)
    placed = page.input_value("input[name=x]")
    assert len(placed.partition(".")[2]) == 3  # the pose a click gives, to the millimetre
    page.fill("input[name=x]", "30.013")  # a click rarely lands on a whole centimetre
    page.fill("input[name=y]", "7.507")
    page.select_option("select[name=links_to]", "RoomB")
    page.click("#tag-save")
    expect(page.locator("#tag-messages .alert.ok")).to_contain_text("saved")
    tags = page.request.get(demo.url(f"/api/tags/?building={BUILDING}&map=CorridorC")).json()
    assert any(abs(tag["x"] - 30.013) < 1e-6 and abs(tag["y"] - 7.507) < 1e-6 for tag in tags)
