"""Tags over the API: placement rules and printing at true size."""

from __future__ import annotations

import io

import cv2
import numpy as np
import pytest
import zxingcpp
from django.contrib.auth.models import User
from PIL import Image

from maps.models import Building, EnvironmentalTag, SubMap
from tests.conftest import client_for, make_submap, make_tag


@pytest.fixture
def corridor(building: Building) -> SubMap:
    make_submap(building, code="Atrium1")
    return make_submap(building, code="CorridorA")


def new_tag(**kwargs: object) -> dict[str, object]:
    tag = {
        "building": "boccioni_1",
        "submap": "CorridorA",
        "marker_id": 7,
        "x": 1.0,
        "y": 0.5,
        "yaw": 1.57,
        "links_to": "Atrium1",
    }
    return {**tag, **kwargs}


def test_an_admin_places_a_tag_and_reads_its_payload(corridor: SubMap, admin: User) -> None:
    response = client_for(admin).post("/api/tags/", new_tag(), format="json")
    assert response.status_code == 201, response.json()
    assert response.json()["payload"] == "http://127.0.0.1:8000, 56037, boccioni_1, Atrium1"
    assert response.json()["size"] == 0.06


@pytest.mark.parametrize(
    ("change", "field"),
    [
        ({"submap": "Nowhere"}, "submap"),
        ({"links_to": "Nowhere"}, "links_to"),
        ({"marker_id": 587}, "marker_id"),
        ({"marker_id": -1}, "marker_id"),
        ({"x": "left"}, "x"),
        ({"size": 0.0}, "size"),
    ],
)
def test_it_refuses_a_bad_tag_naming_the_field(
    corridor: SubMap, admin: User, change: dict[str, object], field: str
) -> None:
    response = client_for(admin).post("/api/tags/", new_tag(**change), format="json")
    assert response.status_code == 400
    assert field in response.json()
    assert not EnvironmentalTag.objects.exists()


def test_marker_ids_are_unique_in_a_building(corridor: SubMap, admin: User) -> None:
    make_tag(corridor, marker_id=7)
    response = client_for(admin).post("/api/tags/", new_tag(), format="json")
    assert response.status_code == 400
    assert "marker_id" in response.json()


def test_a_payload_too_long_for_qr_version_3_is_refused(
    corridor: SubMap, admin: User, settings: object
) -> None:
    settings.CLOUDNAV_PUBLIC_URL = "https://a-very-long-cloud-host-name.example.org:8443"  # type: ignore[attr-defined]
    response = client_for(admin).post("/api/tags/", new_tag(), format="json")
    assert response.status_code == 400
    assert "links_to" in response.json()


def decode(png: bytes) -> tuple[list[int], list[str]]:
    grey = np.array(Image.open(io.BytesIO(png)).convert("L"))
    dictionary = cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_APRILTAG_36h11)
    _, ids, _ = cv2.aruco.ArucoDetector(dictionary).detectMarkers(grey)
    texts = [r.text for r in zxingcpp.read_barcodes(grey)]
    return ([] if ids is None else [int(i) for i in ids.ravel()]), texts


def test_the_printed_png_reads_back_as_its_marker_and_payload(
    corridor: SubMap, viewer: User
) -> None:
    tag = make_tag(corridor, marker_id=12, links_to=SubMap.objects.get(code="Atrium1"))
    response = client_for(viewer).get(f"/api/tags/{tag.pk}/print.png")
    assert response["Content-Type"] == "image/png"
    assert decode(response.content) == ([12], ["http://127.0.0.1:8000, 56037, boccioni_1, Atrium1"])
    dpi = Image.open(io.BytesIO(response.content)).info["dpi"]
    assert round(dpi[0]) == 300


def test_the_building_sheet_is_one_pdf_with_every_tag(corridor: SubMap, viewer: User) -> None:
    for marker in range(14):
        make_tag(corridor, marker_id=marker)
    response = client_for(viewer).get("/api/buildings/boccioni_1/tags/print.pdf")
    assert response["Content-Type"] == "application/pdf"
    assert response.content.startswith(b"%PDF")
    assert response.content.count(b"/Type /Page\n") + response.content.count(b"/Type /Page ") >= 1


def test_a_single_tag_pdf_is_a4(corridor: SubMap, viewer: User) -> None:
    tag = make_tag(corridor)
    content = client_for(viewer).get(f"/api/tags/{tag.pk}/print.pdf").content
    assert b"/MediaBox [ 0 0 595" in content or b"/MediaBox [0 0 595" in content
