"""Roles per building: a person's role is held by their membership of each building.

Expected: a building's admins list, add, re-role and remove members through the API (4xx
with field errors on bad input; nobody else may); an operator of one building who is a
viewer of another drives robots in the first and not in the second; lowering a role
closes the person's open rosbridge connections, as removing the membership does; a
building keeps at least one admin; memberships made without a role take the group's."""

from __future__ import annotations

from typing import Any

import pytest
from channels.db import database_sync_to_async
from django.contrib.auth.models import User

from maps.access import Role, role_in
from maps.models import Building, Membership
from tests.conftest import client_for, make_building, make_robot, make_user
from tests.support.teleop import GO, ZERO
from tests.support.tenants import closed_soon

MEMBERS = "/api/buildings/boccioni_1/members/"


def member(name: str) -> str:
    return f"{MEMBERS}{name}/"


@pytest.mark.django_db
def test_members_are_listed_with_their_role(building: Building, viewer: User) -> None:
    answer = client_for(viewer).get(MEMBERS)
    assert answer.status_code == 200
    assert answer.json() == [
        {"username": "admin", "role": "admin"},
        {"username": "operator", "role": "operator"},
        {"username": "viewer", "role": "viewer"},
    ]


@pytest.mark.django_db
def test_an_admin_adds_a_member_with_a_role_and_changes_it(building: Building, admin: User) -> None:
    newcomer = make_user("newcomer", "viewer")
    api = client_for(admin)
    added = api.post(MEMBERS, {"username": "newcomer", "role": "operator"}, format="json")
    assert added.status_code == 201, added.content
    assert added.json() == {"username": "newcomer", "role": "operator"}
    assert role_in(newcomer, building) is Role.OPERATOR
    changed = api.patch(member("newcomer"), {"role": "viewer"}, format="json")
    assert changed.status_code == 200, changed.content
    assert role_in(User.objects.get(pk=newcomer.pk), building) is Role.VIEWER
    assert api.delete(member("newcomer")).status_code == 204
    assert role_in(User.objects.get(pk=newcomer.pk), building) is Role.NONE


@pytest.mark.django_db
def test_a_member_added_without_a_role_gets_their_groups(building: Building, admin: User) -> None:
    make_user("newcomer", "operator")
    added = client_for(admin).post(MEMBERS, {"username": "newcomer"}, format="json")
    assert added.json() == {"username": "newcomer", "role": "operator"}
    assert Membership.objects.get(user__username="newcomer").role == "operator"


@pytest.mark.django_db
@pytest.mark.parametrize(
    ("method", "url", "body", "field"),
    [
        ("post", MEMBERS, {"username": "nobody", "role": "viewer"}, "username"),
        ("post", MEMBERS, {"username": "viewer", "role": "viewer"}, "username"),
        ("post", MEMBERS, {"username": "newcomer", "role": "owner"}, "role"),
        ("post", MEMBERS, {"role": "viewer"}, "username"),
        ("patch", member("operator"), {"role": "superuser"}, "role"),
        ("patch", member("operator"), {}, "role"),
    ],
)
def test_bad_input_is_refused_with_field_errors(
    building: Building, admin: User, method: str, url: str, body: dict[str, Any], field: str
) -> None:
    make_user("newcomer", "viewer")
    answer = getattr(client_for(admin), method)(url, body, format="json")
    assert answer.status_code == 400
    assert field in answer.json()
    assert role_in(User.objects.get(username="operator"), building) is Role.OPERATOR


@pytest.mark.django_db
@pytest.mark.parametrize("who", ["operator", "viewer", "outsider"])
def test_only_the_buildings_admins_change_roles(building: Building, who: str) -> None:
    person = User.objects.get(username=who) if who != "outsider" else make_user(who, "admin")
    api = client_for(person)
    promoted = api.patch(member(who if who != "outsider" else "viewer"), {"role": "admin"})
    added = api.post(MEMBERS, {"username": "admin", "role": "viewer"}, format="json")
    removed = api.delete(member("viewer"))
    expected = 404 if who == "outsider" else 403  # an outsider is not told it exists
    assert (promoted.status_code, added.status_code, removed.status_code) == (expected,) * 3
    assert dict(Membership.objects.values_list("user__username", "role")) == {
        "admin": "",
        "operator": "",
        "viewer": "",
    }


@pytest.mark.django_db
def test_a_buildings_admin_in_the_viewer_group_manages_it_and_no_other(viewer: User) -> None:
    mine = make_building(code="mine_1")
    Membership.objects.create(building=mine, user=viewer, role="admin")
    make_user("newcomer", "viewer")
    api = client_for(viewer)
    ok = api.post("/api/buildings/mine_1/members/", {"username": "newcomer"}, format="json")
    assert ok.status_code == 201
    theirs = make_building(code="theirs_1", members=[viewer])
    assert role_in(viewer, theirs) is Role.VIEWER
    answer = api.post("/api/buildings/theirs_1/members/", {"username": "newcomer"})
    assert answer.status_code == 403


@pytest.mark.django_db
def test_the_last_admin_is_not_demoted_nor_removed(building: Building, admin: User) -> None:
    api = client_for(admin)
    demoted = api.patch(member("admin"), {"role": "viewer"}, format="json")
    assert demoted.status_code == 400
    assert "role" in demoted.json()
    removed = api.delete(member("admin"))
    assert removed.status_code == 400
    assert "username" in removed.json()
    assert api.patch(member("operator"), {"role": "admin"}, format="json").status_code == 200
    assert api.patch(member("admin"), {"role": "viewer"}, format="json").status_code == 200


@pytest.mark.django_db
def test_superusers_stay_admins_everywhere(building: Building) -> None:
    root = User.objects.create_superuser("root", password="pw")
    assert role_in(root, building) is Role.ADMIN
    assert client_for(root).patch(member("viewer"), {"role": "operator"}).status_code == 200


# ---------------------------------------------------------------- driving per building


@pytest.fixture
def two_buildings(building: Building, operator: User) -> dict[str, str]:
    """``operator`` operates boccioni_1 (robot r1) and only views annex_1 (robot r2)."""
    annex = make_building(code="annex_1", name="Annex")
    Membership.objects.create(building=annex, user=operator, role="viewer")
    return {
        "r1": make_robot(name="r1", buildings=[building])[1],
        "r2": make_robot(name="r2", buildings=[annex])[1],
    }


async def listening(rosbridge: Any, token: str) -> Any:
    robot = await rosbridge(token=token)
    await robot.send(op="subscribe", topic="cmd_vel")
    await robot.sync()
    return robot


async def lock(client: Any, robot: str) -> dict[str, Any]:
    answer = await client.call("/cloudnav/teleop_lock", {"robot": robot, "action": "acquire"})
    return answer


@pytest.mark.django_db(transaction=True)
async def test_an_operator_drives_where_they_operate_and_not_where_they_view(
    rosbridge: Any, two_buildings: dict[str, str], operator: User
) -> None:
    r1 = await listening(rosbridge, two_buildings["r1"])
    r2 = await listening(rosbridge, two_buildings["r2"])
    driver = await rosbridge(user=operator)
    assert (await lock(driver, "r1"))["values"]["success"] is True
    answer = await lock(driver, "r2")
    assert answer["result"] is False or answer["values"]["success"] is False
    await driver.send(op="publish", topic="/r2/cmd_vel", msg=GO)
    await driver.send(op="publish", topic="/r1/cmd_vel", msg=GO)
    assert (await r1.receive())["msg"] == GO
    assert await r2.quiet()


@pytest.mark.django_db(transaction=True)
@pytest.mark.parametrize("change", ["demoted", "removed"])
async def test_an_operator_demoted_in_a_building_loses_teleop_on_open_sockets(
    rosbridge: Any, two_buildings: dict[str, str], operator: User, change: str
) -> None:
    robot = await listening(rosbridge, two_buildings["r1"])
    driver = await rosbridge(user=operator)
    assert (await lock(driver, "r1"))["values"]["success"] is True

    def lower() -> None:
        membership = Membership.objects.get(building__code="boccioni_1", user=operator)
        if change == "demoted":
            membership.role = "viewer"
            membership.save()
        else:
            client_for(User.objects.get(username="admin")).delete(member("operator"))

    await database_sync_to_async(lower)()
    assert await closed_soon(driver)
    assert (await robot.receive())["msg"] == ZERO  # the lock holder left: the robot stops
    again = await rosbridge(user=await database_sync_to_async(User.objects.get)(pk=operator.pk))
    answer = await lock(again, "r1")
    assert answer["result"] is False or answer["values"]["success"] is False
    await again.send(op="publish", topic="/r1/cmd_vel", msg=GO)
    await again.sync()
    assert await robot.quiet()


@pytest.mark.django_db(transaction=True)
async def test_a_promotion_takes_effect_on_reconnecting(
    rosbridge: Any, two_buildings: dict[str, str], operator: User
) -> None:
    def promote() -> None:
        answer = client_for(User.objects.get(username="admin")).patch(
            "/api/buildings/annex_1/members/operator/", {"role": "operator"}, format="json"
        )
        assert answer.status_code == 404  # admin is no member of annex_1
        root = User.objects.create_superuser("root", password="pw")
        answer = client_for(root).patch(
            "/api/buildings/annex_1/members/operator/", {"role": "operator"}, format="json"
        )
        assert answer.status_code == 200

    await database_sync_to_async(promote)()
    robot = await listening(rosbridge, two_buildings["r2"])
    driver = await rosbridge(user=await database_sync_to_async(User.objects.get)(pk=operator.pk))
    assert (await lock(driver, "r2"))["values"]["success"] is True
    await driver.send(op="publish", topic="/r2/cmd_vel", msg=GO)
    assert (await robot.receive())["msg"] == GO


@pytest.mark.django_db
def test_an_admin_links_robots_only_to_buildings_they_administer(admin: User) -> None:
    mine = make_building(code="mine_1")
    Membership.objects.create(building=mine, user=admin, role="admin")
    viewed = make_building(code="viewed_1")
    Membership.objects.create(building=viewed, user=admin, role="viewer")
    api = client_for(admin)
    refused = api.post("/api/robots/", {"name": "r7", "buildings": ["viewed_1"]}, format="json")
    assert refused.status_code == 400
    assert "buildings" in refused.json()
    made = api.post("/api/robots/", {"name": "r7", "buildings": ["mine_1"]}, format="json")
    assert made.status_code == 201, made.content
