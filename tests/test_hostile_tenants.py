"""Tenants stay apart (issue 9, points 3 and 4): what one tenant's people and robots can
do to another tenant's.

REST: a robot shared by two tenants' buildings is renamed, described, rotated and deleted
only by an admin of all its buildings; each admin links and unlinks their own buildings
only, and sees no other tenant's building codes or users, in answers and in the browsable
API's forms; a tag is refused before it is validated.
"""

from __future__ import annotations

from typing import Any

import pytest
from django.contrib.auth.models import User

from maps.models import Building
from robots.models import Robot
from tests.conftest import client_for, make_building, make_robot, make_submap, make_user


@pytest.fixture
def tenants(building: Building, admin: User) -> Any:
    """``boccioni_1`` (admin) and ``theirs_1`` (their_admin, their_user) share robot r1."""
    their_admin = make_user("their_admin", "admin")
    their_user = make_user("their_user", "viewer")
    theirs = make_building(code="theirs_1", name="Theirs", members=[their_admin, their_user])
    make_submap(theirs, code="Secret")
    robot, token = make_robot(name="r1", buildings=[building, theirs])
    return robot, token, theirs


def codes(robot: Robot) -> set[str]:
    return set(robot.buildings.values_list("code", flat=True))


@pytest.mark.parametrize(
    ("method", "path", "body"),
    [
        ("patch", "/api/robots/r1/", {"name": "r9"}),
        ("patch", "/api/robots/r1/", {"description": "mine now"}),
        ("put", "/api/robots/r1/", {"name": "r9", "buildings": ["boccioni_1"]}),
        ("delete", "/api/robots/r1/", None),
        ("post", "/api/robots/r1/rotate_token", None),
    ],
)
def test_an_admin_of_one_building_cannot_change_a_shared_robot_for_all(
    tenants: Any, admin: User, method: str, path: str, body: Any
) -> None:
    robot, _, _ = tenants
    before = Robot.objects.values().get(pk=robot.pk)
    response = getattr(client_for(admin), method)(path, body, format="json")
    assert response.status_code == 403, response.content
    assert Robot.objects.values().get(pk=robot.pk) == before
    assert codes(robot) == {"boccioni_1", "theirs_1"}


def test_an_admin_links_and_unlinks_their_own_buildings_only(
    tenants: Any, admin: User, building: Building
) -> None:
    robot, _, _ = tenants
    make_building(code="mine_2", members=[admin])
    client = client_for(admin)
    answer = client.patch("/api/robots/r1/", {"buildings": ["mine_2"]}, format="json")
    assert answer.status_code == 200
    assert answer.json()["buildings"] == ["mine_2"]
    assert codes(robot) == {"mine_2", "theirs_1"}
    refused = client.patch("/api/robots/r1/", {"buildings": ["theirs_1"]}, format="json")
    assert refused.status_code == 400
    assert codes(robot) == {"mine_2", "theirs_1"}
    assert client.patch("/api/robots/r1/", {"buildings": []}, format="json").status_code == 200
    assert codes(robot) == {"theirs_1"}


def test_an_admin_of_every_building_renames_rotates_and_deletes(tenants: Any, admin: User) -> None:
    _, _, theirs = tenants
    theirs.members.add(admin)
    client = client_for(admin)
    assert client.patch("/api/robots/r1/", {"name": "r9"}, format="json").status_code == 200
    assert client.post("/api/robots/r9/rotate_token").status_code == 200
    assert client.delete("/api/robots/r9/").status_code == 204


@pytest.mark.parametrize(
    "path", ["/api/robots/", "/api/robots/r1/", "/api/fleet/", "/api/buildings/"]
)
def test_answers_name_no_other_tenants_building(tenants: Any, admin: User, path: str) -> None:
    response = client_for(admin).get(path, HTTP_ACCEPT="application/json")
    assert response.status_code == 200
    assert "theirs_1" not in response.content.decode()
    assert "their_" not in response.content.decode()


def test_a_robot_sees_no_building_of_another_tenant_in_the_fleet(tenants: Any) -> None:
    other = make_building(code="elsewhere")
    _, token = make_robot(name="r2", buildings=[Building.objects.get(code="boccioni_1"), other])
    body = client_for(token).get("/api/fleet/").content.decode()
    assert "theirs_1" not in body


@pytest.mark.parametrize(
    "path", ["/api/robots/", "/api/robots/r1/", "/api/buildings/", "/api/tags/"]
)
def test_browsable_forms_list_nothing_foreign(tenants: Any, admin: User, path: str) -> None:
    page = client_for(admin).get(path, HTTP_ACCEPT="text/html").content.decode()
    assert "theirs_1" not in page
    assert "their_admin" not in page
    assert "their_user" not in page


def test_an_admin_cannot_add_another_tenants_user_to_their_building(
    tenants: Any, admin: User
) -> None:
    response = client_for(admin).patch(
        "/api/buildings/boccioni_1/", {"members": ["admin", "their_user"]}, format="json"
    )
    assert response.status_code == 400
    assert not Building.objects.get(code="boccioni_1").members.filter(username="their_user")


def test_a_user_of_no_building_yet_can_be_added(tenants: Any, admin: User) -> None:
    make_user("newcomer", "viewer")
    response = client_for(admin).patch(
        "/api/buildings/boccioni_1/", {"members": ["admin", "newcomer"]}, format="json"
    )
    assert response.status_code == 200


@pytest.mark.parametrize(
    "tag",
    [
        {"submap": "Secret", "links_to": "Secret", "marker_id": 3},  # valid there
        {"submap": "Nope", "links_to": "Nope", "marker_id": 10**6},  # invalid there
    ],
)
def test_a_tag_in_another_tenants_building_is_refused_before_it_is_validated(
    tenants: Any, admin: User, tag: dict[str, Any]
) -> None:
    body = {"building": "theirs_1", "x": 1, "y": 1, "yaw": 0, **tag}
    response = client_for(admin).post("/api/tags/", body, format="json")
    assert response.status_code == 404
    assert "Secret" not in response.content.decode()
    assert "marker" not in response.content.decode()
