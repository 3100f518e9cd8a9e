"""The robot's map bundle: one response with everything, and conditional requests."""

from __future__ import annotations

import base64
from typing import Any

import pytest
from django.contrib.auth.models import User

from maps import services
from maps.domain.mapfile import parse_map_yaml
from maps.domain.topology import Edge
from maps.models import Building, SubMap
from tests.conftest import client_for, make_robot, make_submap, make_tag, map_pgm, map_yaml

URL = "/api/buildings/boccioni_1/maps/CorridorA/bundle"


@pytest.fixture
def corridor(building: Building) -> SubMap:
    corridor = make_submap(building, code="CorridorA")
    atrium = make_submap(building, code="Atrium1")
    make_tag(corridor, marker_id=3, links_to=atrium)
    services.replace_topology(building, {}, [Edge("CorridorA", "Atrium1", 4.0)])
    return corridor


def fetch(token: str, etag: str | None = None) -> Any:
    headers = {"If-None-Match": etag} if etag else {}
    return client_for(token).get(URL, headers=headers)


def test_it_holds_the_image_yaml_tags_and_topology(corridor: SubMap, token: str) -> None:
    response = fetch(token)
    body = response.json()
    assert base64.b64decode(body["image"]["data"]) == map_pgm()
    assert parse_map_yaml(body["yaml"]).image == body["image"]["name"]
    assert [t["marker_id"] for t in body["tags"]] == [3]
    assert body["tags"][0]["links_to"] == "Atrium1"
    assert body["topology"]["edges"] == [{"a": "Atrium1", "b": "CorridorA", "cost": 4.0}]
    assert body["map_id"] == "boccioni_1/CorridorA"
    assert response["ETag"].startswith('"')


def test_it_answers_304_when_unchanged(corridor: SubMap, token: str) -> None:
    etag = fetch(token)["ETag"]
    response = fetch(token, etag)
    assert response.status_code == 304
    assert response.content == b""
    assert response["ETag"] == etag


def test_it_answers_200_to_a_stale_etag(corridor: SubMap, token: str) -> None:
    assert fetch(token, '"stale"').status_code == 200


def change_image(corridor: SubMap) -> None:
    make_submap(corridor.building, code="CorridorA", image=map_pgm(width=41), replace=True)


def change_yaml(corridor: SubMap) -> None:
    services.update_submap(corridor, {"resolution": 0.1})


def change_tag(corridor: SubMap) -> None:
    corridor.tags.update(x=3.0)


def add_tag(corridor: SubMap) -> None:
    make_tag(corridor, marker_id=9)


def change_topology(corridor: SubMap) -> None:
    services.replace_topology(corridor.building, {}, [Edge("CorridorA", "Atrium1", 5.0)])


@pytest.mark.parametrize(
    "change", [change_image, change_yaml, change_tag, add_tag, change_topology]
)
def test_the_etag_changes_with_everything_the_bundle_holds(
    corridor: SubMap, token: str, change: Any
) -> None:
    etag = fetch(token)["ETag"]
    change(corridor)
    response = fetch(token, etag)
    assert response.status_code == 200
    assert response["ETag"] != etag


def test_a_robot_of_another_building_gets_403_and_no_data(corridor: SubMap) -> None:
    other = Building.objects.create(code="other_1", name="Other")
    _, foreign = make_robot(name="r2", buildings=[other])
    response = fetch(foreign)
    assert response.status_code == 403
    assert b"data" not in response.content


def test_an_unregistered_robot_gets_401(corridor: SubMap) -> None:
    assert fetch("cnr_forged").status_code == 401


def test_a_rotated_token_stops_working(corridor: SubMap, token: str, admin: User) -> None:
    client_for(admin).post("/api/robots/r1/rotate_token")
    assert fetch(token).status_code == 401


def test_a_sub_map_with_a_colour_png_travels_as_uploaded(building: Building, token: str) -> None:
    from io import BytesIO

    from PIL import Image

    png = BytesIO()
    Image.new("RGB", (8, 6), (250, 250, 250)).save(png, "PNG")
    make_submap(building, code="CorridorA", image=png.getvalue(), yaml=map_yaml(image="map.pgm"))
    body = fetch(token).json()
    assert base64.b64decode(body["image"]["data"]) == png.getvalue()
