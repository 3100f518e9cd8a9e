"""Sub-map upload, edit, conversion and export over the REST API."""

from __future__ import annotations

import io
import json
import zipfile
from typing import Any

import numpy as np
import pytest
from django.contrib.auth.models import User
from django.core.files.uploadedfile import SimpleUploadedFile
from PIL import Image

from maps.domain.mapfile import occupancy_from_image, parse_map_yaml
from maps.models import Building, SubMap
from tests.conftest import client_for, make_submap, map_pgm, map_yaml
from tests.support.submap_uploads import BAD_UPLOADS, URL, pair, post, unread, zipped


def test_it_stores_an_image_and_yaml_pair(building: Building, admin: User) -> None:
    response = post(admin, pair(name="Corridor A"))
    assert response.status_code == 201, response.json()
    body = response.json()
    assert body["map_id"] == "boccioni_1/CorridorA"
    assert (body["width"], body["height"], body["resolution"]) == (40, 30, 0.05)
    assert body["origin"] == [0.0, 0.0, 0.0]


def test_it_stores_a_zip_of_both(building: Building, admin: User) -> None:
    archive = zipped(
        {"maps/corridor.yaml": map_yaml(image="corridor.pgm"), "maps/corridor.pgm": map_pgm()}
    )
    response = post(admin, {"code": "CorridorA", "archive": archive})
    assert response.status_code == 201, response.json()
    assert SubMap.objects.get().image_name == "corridor.pgm"


def test_uploading_an_existing_code_replaces_its_map_and_version(
    building: Building, admin: User
) -> None:
    first = post(admin, pair()).json()["content_hash"]
    wider = SimpleUploadedFile("map.pgm", map_pgm(width=50))
    response = post(admin, pair(image=wider, replace="true"))
    assert response.status_code == 200
    assert response.json()["width"] == 50
    assert response.json()["content_hash"] != first
    assert response.json()["version"] == 2
    assert SubMap.objects.count() == 1


def test_uploading_an_existing_code_without_replace_is_refused_and_keeps_the_map(
    building: Building, admin: User
) -> None:
    before = make_submap(building)
    response = post(admin, pair(image=SimpleUploadedFile("map.pgm", map_pgm(width=50))))
    assert response.status_code == 409
    assert "boccioni_1/CorridorA already exists" in response.json()["code"][0]
    assert "replace=true" in response.json()["code"][0]
    assert SubMap.objects.get().version == before.version
    assert post(admin, pair(replace="false")).status_code == 409


@pytest.mark.parametrize(("what", "change", "field"), BAD_UPLOADS, ids=[c[0] for c in BAD_UPLOADS])
def test_it_refuses_a_bad_upload_naming_the_field_and_stores_nothing(
    building: Building, admin: User, what: str, change: dict[str, Any], field: str
) -> None:
    response = post(admin, pair(**unread(change)))
    assert response.status_code == 400
    assert field in response.json(), response.json()
    assert not SubMap.objects.exists()


def test_it_refuses_an_image_over_the_pixel_limit(
    building: Building, admin: User, settings: Any
) -> None:
    settings.CLOUDNAV_MAX_MAP_PIXELS = 1000
    response = post(admin, pair())
    assert response.status_code == 400
    assert "image" in response.json()
    assert not SubMap.objects.exists()


@pytest.mark.parametrize("name", ["../evil.pgm", "/abs/map.pgm", "a/../../map.pgm"])
def test_it_refuses_a_zip_member_escaping_the_archive(
    building: Building, admin: User, name: str
) -> None:
    archive = zipped({"map.yaml": map_yaml(image="map.pgm"), name: map_pgm()})
    response = post(admin, {"code": "CorridorA", "archive": archive})
    assert response.status_code == 400
    assert "archive" in response.json()
    assert not SubMap.objects.exists()


CONTROL_NAMES = ["map\r\n.pgm", "map\n.pgm", "map\r.pgm", "map\x1b.pgm"]


@pytest.mark.parametrize("name", CONTROL_NAMES, ids=repr)
def test_it_refuses_a_zip_member_name_with_a_control_character(
    building: Building, admin: User, name: str
) -> None:
    archive = zipped({"map.yaml": map_yaml(image=json.dumps(name)), name: map_pgm()})
    response = post(admin, {"code": "CorridorA", "archive": archive})
    assert response.status_code == 400
    assert "control character" in response.json()["archive"][0]
    assert not SubMap.objects.exists()


@pytest.mark.parametrize("name", CONTROL_NAMES, ids=repr)
def test_it_serves_the_image_of_a_name_stored_with_a_control_character(
    building: Building, viewer: User, name: str
) -> None:
    make_submap(building)
    SubMap.objects.update(image_name=name)
    response = client_for(viewer).get(f"{URL}CorridorA/image")
    assert response.status_code == 200
    assert response.content == map_pgm()
    disposition = response["Content-Disposition"]
    assert disposition.startswith("inline; filename")
    assert all(char.isprintable() for char in disposition)


def test_the_image_keeps_its_name_in_the_content_disposition(
    building: Building, viewer: User
) -> None:
    make_submap(building)
    response = client_for(viewer).get(f"{URL}CorridorA/image")
    assert response["Content-Disposition"] == 'inline; filename="map.pgm"'


def test_a_bad_replacement_keeps_the_old_map(building: Building, admin: User) -> None:
    before = make_submap(building)
    response = post(admin, pair(image=SimpleUploadedFile("map.pgm", b"P5\n40 30\n255\n")))
    assert response.status_code == 400
    assert SubMap.objects.get().version == before.version


def test_editing_metadata_changes_the_version(building: Building, admin: User) -> None:
    submap = make_submap(building)
    response = client_for(admin).patch(f"{URL}CorridorA/", {"origin": [1, 2, 0.5]}, format="json")
    assert response.status_code == 200
    assert response.json()["origin"] == [1.0, 2.0, 0.5]
    assert response.json()["content_hash"] != submap.version


def test_editing_metadata_into_an_invalid_state_is_refused_whole(
    building: Building, admin: User
) -> None:
    submap = make_submap(building)
    changes = {"free_thresh": 0.9, "name": "Renamed"}
    response = client_for(admin).patch(f"{URL}CorridorA/", changes, format="json")
    assert response.status_code == 400
    assert "free_thresh" in response.json()
    submap.refresh_from_db()
    assert submap.name != "Renamed"


def test_it_serves_the_map_as_an_occupancy_grid_bottom_row_first(
    building: Building, viewer: User
) -> None:
    make_submap(building, yaml=map_yaml(origin=[-1.0, -2.0, 0.0]))
    grid = client_for(viewer).get(f"{URL}CorridorA/grid").json()
    assert grid["header"]["frame_id"] == "boccioni_1/CorridorA"
    info = grid["info"]
    assert (info["width"], info["height"], info["resolution"]) == (40, 30, 0.05)
    assert info["origin"]["position"]["x"] == -1.0
    rows = np.array(grid["data"]).reshape(30, 40)
    assert rows[0, 5] == 100  # the bottom wall
    assert rows[-2, 2] == -1  # the unknown patch drawn in the image's top-left corner
    assert rows[10, 10] == 0


def test_it_serves_the_image_as_uploaded(building: Building, viewer: User) -> None:
    make_submap(building)
    response = client_for(viewer).get(f"{URL}CorridorA/image")
    assert response.content == map_pgm()
    assert response["Content-Type"] == "image/x-portable-graymap"


def test_export_gives_a_pair_that_loads_to_the_same_grid(building: Building, viewer: User) -> None:
    make_submap(building, yaml=map_yaml(origin=[1.5, -2.0, 0.0]))
    client = client_for(viewer)
    response = client.get(f"{URL}CorridorA/export")
    with zipfile.ZipFile(io.BytesIO(response.content)) as archive:
        meta = parse_map_yaml(archive.read("CorridorA.yaml"))
        image = Image.open(io.BytesIO(archive.read(meta.image)))
    grid = client.get(f"{URL}CorridorA/grid").json()
    assert meta.origin == (1.5, -2.0, 0.0)
    assert occupancy_from_image(image, meta).ravel().tolist() == grid["data"]
