"""Parking spots over the API: part of the building, admins edit them, members read them,
bad input is refused naming the field and stores nothing."""

from __future__ import annotations

import pytest
from django.contrib.auth.models import User

from maps.models import Building, ParkingSpot, SubMap
from tests.conftest import client_for, make_building, make_submap

URL = "/api/buildings/boccioni_1/parking/"


@pytest.fixture
def corridor(building: Building) -> SubMap:
    return make_submap(building, code="CorridorA")


def new_spot(**kwargs: object) -> dict[str, object]:
    return {"name": "by the lift", "map": "CorridorA", "x": 1.0, "y": 0.75, "yaw": 0.0, **kwargs}


def make_spot(submap: SubMap, **kwargs: object) -> ParkingSpot:
    kwargs.setdefault("name", "by the lift")
    kwargs.setdefault("x", 1.0)
    kwargs.setdefault("y", 0.75)
    return ParkingSpot.objects.create(building=submap.building, submap=submap, **kwargs)


def test_an_admin_places_a_spot_and_members_read_it(
    corridor: SubMap, admin: User, viewer: User
) -> None:
    created = client_for(admin).post(URL, new_spot(), format="json")
    assert created.status_code == 201, created.json()
    assert created.json()["map_id"] == "boccioni_1/CorridorA"
    listed = client_for(viewer).get(URL)
    assert listed.status_code == 200
    assert [(s["name"], s["x"], s["y"]) for s in listed.json()] == [("by the lift", 1.0, 0.75)]


@pytest.mark.parametrize(
    ("change", "field"),
    [
        ({"map": "Nowhere"}, "map"),
        ({"x": "left"}, "x"),
        ({"y": 1e9}, "y"),
        ({"x": 0.0, "y": 0.0}, "x"),  # in the wall
        ({"x": 1.0, "y": 0.1}, "y"),  # too near it for the robot
        ({"name": ""}, "name"),
        ({"name": "x" * 61}, "name"),
    ],
)
def test_it_refuses_a_bad_spot_naming_the_field(
    corridor: SubMap, admin: User, change: dict[str, object], field: str
) -> None:
    response = client_for(admin).post(URL, new_spot(**change), format="json")
    assert response.status_code == 400
    assert field in response.json()
    assert not ParkingSpot.objects.exists()


def test_two_spots_of_a_building_cannot_share_a_name(corridor: SubMap, admin: User) -> None:
    make_spot(corridor)
    response = client_for(admin).post(URL, new_spot(x=1.2), format="json")
    assert response.status_code == 400
    assert "name" in response.json()


def test_an_admin_drags_and_deletes_a_spot(corridor: SubMap, admin: User) -> None:
    spot = make_spot(corridor)
    moved = client_for(admin).patch(f"{URL}{spot.pk}/", {"x": 1.3}, format="json")
    assert moved.status_code == 200, moved.json()
    spot.refresh_from_db()
    assert (spot.x, spot.y) == (1.3, 0.75)
    assert client_for(admin).delete(f"{URL}{spot.pk}/").status_code == 204
    assert not ParkingSpot.objects.exists()


def test_a_spot_cannot_be_dragged_into_a_wall(corridor: SubMap, admin: User) -> None:
    spot = make_spot(corridor)
    response = client_for(admin).patch(f"{URL}{spot.pk}/", {"y": 0.0}, format="json")
    assert response.status_code == 400
    assert "y" in response.json()
    spot.refresh_from_db()
    assert spot.y == 0.75


@pytest.mark.parametrize("role", ["operator", "viewer"])
def test_members_below_admin_may_not_edit_spots(
    corridor: SubMap, role: str, request: pytest.FixtureRequest
) -> None:
    person = request.getfixturevalue(role)
    spot = make_spot(corridor)
    client = client_for(person)
    assert client.post(URL, new_spot(name="other"), format="json").status_code == 403
    assert client.patch(f"{URL}{spot.pk}/", {"x": 1.3}, format="json").status_code == 403
    assert client.delete(f"{URL}{spot.pk}/").status_code == 403
    assert ParkingSpot.objects.get().x == 1.0


def test_it_rejects_outsider(corridor: SubMap, outsider: User) -> None:
    spot = make_spot(corridor)
    client = client_for(outsider)
    assert client.get(URL).status_code == 404
    assert client.get(f"{URL}{spot.pk}/").status_code == 404
    assert client.post(URL, new_spot(name="other"), format="json").status_code == 404
    assert client.delete(f"{URL}{spot.pk}/").status_code == 404
    assert ParkingSpot.objects.count() == 1


def test_a_spot_of_another_building_is_not_found_through_this_one(
    corridor: SubMap, admin: User
) -> None:
    other = make_building(code="other", members=[admin])
    spot = make_spot(make_submap(other, code="Hall"), name="hall")
    assert client_for(admin).get(f"{URL}{spot.pk}/").status_code == 404
    assert client_for(admin).delete(f"{URL}{spot.pk}/").status_code == 404


def test_it_rejects_anonymous(corridor: SubMap) -> None:
    assert client_for(None).get(URL).status_code in (401, 403)
