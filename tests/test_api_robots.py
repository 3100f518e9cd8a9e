"""The robot registry: tokens shown once, stored hashed, rotated by admins."""

from __future__ import annotations

import io

import pytest
from django.contrib.auth.models import User
from django.core.management import CommandError, call_command

from maps.models import Building
from robots.models import Robot
from robots.tokens import token_digest
from tests.conftest import client_for, make_building, make_robot


def test_registering_shows_the_token_once_and_stores_only_its_hash(
    building: Building, admin: User
) -> None:
    response = client_for(admin).post(
        "/api/robots/", {"name": "tb3_0", "buildings": ["boccioni_1"]}, format="json"
    )
    assert response.status_code == 201
    token = response.json()["token"]
    robot = Robot.objects.get(name="tb3_0")
    assert robot.token_hash == token_digest(token)
    assert token not in str(Robot.objects.values().get())
    assert "token" not in client_for(admin).get("/api/robots/tb3_0/").json()


def test_an_admin_cannot_register_a_robot_for_someone_elses_building(
    building: Building, admin: User
) -> None:
    make_building(code="other_1")
    response = client_for(admin).post(
        "/api/robots/", {"name": "tb3_0", "buildings": ["other_1"]}, format="json"
    )
    assert response.status_code == 400
    assert "buildings" in response.json()


@pytest.mark.parametrize("name", ["1robot", "has space", "a/b", ""])
def test_a_robot_name_must_be_a_ros_name_segment(
    building: Building, admin: User, name: str
) -> None:
    response = client_for(admin).post("/api/robots/", {"name": name}, format="json")
    assert response.status_code == 400
    assert "name" in response.json()


def test_rotating_gives_a_new_token_and_retires_the_old(building: Building, admin: User) -> None:
    robot, old = make_robot(buildings=[building])
    new = client_for(admin).post(f"/api/robots/{robot.name}/rotate_token").json()["token"]
    assert new != old
    assert client_for(old).get("/api/buildings/").status_code == 401
    assert client_for(new).get("/api/buildings/").status_code == 200


def test_admins_see_only_robots_of_their_buildings(building: Building, admin: User) -> None:
    make_robot(name="mine", buildings=[building])
    make_robot(name="theirs", buildings=[make_building(code="other_1")])
    names = [r["name"] for r in client_for(admin).get("/api/robots/").json()]
    assert names == ["mine"]


def test_create_robot_prints_a_working_token(building: Building) -> None:
    out = io.StringIO()
    call_command("create_robot", "tb3_1", "--building", "boccioni_1", stdout=out)
    token = out.getvalue().strip().splitlines()[-1]
    assert Robot.objects.get(name="tb3_1").token_hash == token_digest(token)
    assert client_for(token).get("/api/buildings/boccioni_1/").status_code == 200


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["tb3_1", "--building", "nowhere"], "Unknown building"),
        (["bad name"], "ROS name"),
        (["cloudnav"], "namespace of the server"),
    ],
)
def test_create_robot_refuses_bad_input(building: Building, args: list[str], message: str) -> None:
    with pytest.raises(CommandError, match=message):
        call_command("create_robot", *args, stdout=io.StringIO())


def test_create_robot_refuses_a_duplicate_name(building: Building) -> None:
    make_robot(name="tb3_1")
    with pytest.raises(CommandError, match="already exists"):
        call_command("create_robot", "tb3_1", stdout=io.StringIO())
