"""Rules that hold under odd input and across tenants (issue 23 point 16).

Another tenant's robot is as absent as one that does not exist; an operator of one
tenant never cancels another tenant's mission on a shared robot; a robot's token reads
its own recording and nothing of the building's people; odd dates, NUL bytes and long
names get a 400 with the field, never a 500 (on PostgreSQL too, which refuses what
SQLite lets through).
"""

from __future__ import annotations

import json
from collections.abc import Callable
from typing import Any
from urllib.parse import quote

import pytest
from django.contrib.auth.models import User
from django.core.files.uploadedfile import SimpleUploadedFile

from maps.models import Building
from robots.models import Mission
from tests.conftest import (
    client_for,
    make_building,
    make_robot,
    make_submap,
    make_user,
    map_pgm,
    map_yaml,
)
from tests.fixtures_live import ScaledCluster, run_manage
from tests.support.uploads import basic, request

WAYPOINTS = [{"map": "CorridorA", "x": 1.0, "y": 2.0}]


@pytest.fixture
def tenants(building: Building) -> Any:
    """``boccioni_1`` and ``theirs_1`` (their_operator) share robot r1; r_theirs is
    theirs_1's alone; both buildings have a sub-map CorridorA."""
    their_operator = make_user("their_operator", "operator")
    theirs = make_building(code="theirs_1", name="Theirs", members=[their_operator])
    for place in (building, theirs):  # 5 x 3 m, walled round: waypoints are checked on it
        make_submap(place, code="CorridorA", image=map_pgm(width=100, height=60))
    shared, token = make_robot(name="r1", buildings=[building, theirs])
    make_robot(name="r_theirs", buildings=[theirs])
    return shared, token, their_operator


def start(user: User, robot: str, building: str = "boccioni_1") -> Any:
    body = {"building": building, "robot": robot, "waypoints": WAYPOINTS, "name": "round"}
    return client_for(user).post("/api/missions/", body, format="json")


# ---------------------------------------------------------------- tenants


@pytest.mark.django_db
def test_another_tenants_robot_answers_a_mission_as_a_robot_that_does_not_exist(
    tenants: Any, operator: User
) -> None:
    foreign, absent = start(operator, "r_theirs"), start(operator, "no_such_robot")
    assert (foreign.status_code, foreign.json()) == (absent.status_code, absent.json())
    assert foreign.status_code == 404


@pytest.mark.django_db
def test_another_tenants_operator_does_not_cancel_a_mission_on_a_shared_robot(
    tenants: Any, operator: User
) -> None:
    _, _, their_operator = tenants
    ours = start(operator, "r1").json()
    refused = start(their_operator, "r1", building="theirs_1")
    assert refused.status_code == 409, refused.json()
    assert "operator" not in json.dumps(refused.json())
    mission = Mission.objects.get(pk=ours["id"])
    assert (mission.state, mission.note) == ("running", "")
    assert "their_operator" not in mission.note


@pytest.mark.django_db
def test_an_operator_still_replaces_their_own_buildings_mission(
    tenants: Any, operator: User
) -> None:
    first = start(operator, "r1").json()
    assert start(operator, "r1").status_code == 201
    assert Mission.objects.get(pk=first["id"]).state == "cancelled"


@pytest.mark.django_db
@pytest.mark.parametrize(
    "path",
    [
        "/api/robots/r2/recording.mcap",
        "/api/robots/r2/recording.bag",
        "/api/robots/r2/recording.json",
        "/api/buildings/boccioni_1/recording.mcap",
        "/api/buildings/boccioni_1/recording.bag",
    ],
)
def test_a_robots_token_reads_no_other_robots_recording(building: Building, path: str) -> None:
    _, token = make_robot(name="r1", buildings=[building])
    make_robot(name="r2", buildings=[building])
    assert client_for(token).get(path).status_code == 404
    own = path.replace("r2", "r1").replace("buildings/boccioni_1", "robots/r1")
    assert client_for(token).get(own).status_code == 200


@pytest.mark.django_db
def test_a_robots_token_lists_no_member_of_its_building(building: Building) -> None:
    _, token = make_robot(name="r1", buildings=[building])
    for path in ("/api/buildings/boccioni_1/members/", "/api/buildings/boccioni_1/members/admin/"):
        answer = client_for(token).get(path)
        assert answer.status_code == 403, answer.content
        assert b"admin" not in answer.content


# ---------------------------------------------------------------- odd input


@pytest.mark.django_db
@pytest.mark.parametrize(
    ("query", "field"),
    [
        ("since=2026-02-30T00:00:00", "since"),
        ("until=2026-13-01T00:00:00", "until"),
        ("kind=a%00b", "kind"),
        ("robot=%00", "robot"),
        ("building=x%00", "building"),
        ("severity=%00", "severity"),
    ],
)
def test_odd_event_filters_get_a_field_error(building: Building, viewer: User, query, field):
    answer = client_for(viewer).get(f"/api/events/?{query}")
    assert answer.status_code == 400
    assert field in answer.json()


@pytest.mark.django_db
def test_a_mission_name_over_100_characters_is_refused(tenants: Any, operator: User) -> None:
    body = {"building": "boccioni_1", "robot": "r1", "waypoints": WAYPOINTS, "name": "n" * 101}
    answer = client_for(operator).post("/api/missions/", body, format="json")
    assert answer.status_code == 400
    assert "name" in answer.json()


SEED_SUBMAP = """
import django
django.setup()
from maps.models import Building
from tests.conftest import make_submap
make_submap(Building.objects.get(code="boccioni_1"), code="CorridorA")
print("seeded")
"""


@pytest.mark.scaled
def test_odd_input_gets_400_not_500_on_postgresql(
    scaled_servers: Callable[..., ScaledCluster],
) -> None:
    cluster = scaled_servers(1)
    run_manage(cluster.database_url, "-c", SEED_SUBMAP)
    server, auth = cluster.servers[0], basic("operator")
    for query in ("kind=" + quote("a\0b"), "robot=%00", "since=2026-02-30T00:00:00"):
        status, _, body = request(server, "GET", f"/api/events/?{query}", headers=auth)
        assert status == 400, (query, body)
    mission = {"building": "boccioni_1", "robot": "r1", "waypoints": WAYPOINTS, "name": "n" * 101}
    headers = {**auth, "Content-Type": "application/json"}
    status, _, body = request(
        server, "POST", "/api/missions/", json.dumps(mission).encode(), headers
    )
    assert status == 400, body
    assert "name" in json.loads(body)


@pytest.mark.django_db
@pytest.mark.parametrize(
    "image", [b"garbage" * 10, b"\x89PNG\r\n\x1a\n" + b"\0" * 40, b"GIF89a" + b"\xff" * 20]
)
def test_upload_errors_print_no_memory_address(building: Building, admin: User, image) -> None:
    yaml = _named("map.yaml", map_yaml())
    files = {"code": "Hall", "image": _named("map.pgm", image), "yaml": yaml}
    answer = client_for(admin).post("/api/buildings/boccioni_1/maps/", files, format="multipart")
    assert answer.status_code == 400
    said = json.dumps(answer.json())
    assert "image" in answer.json()
    assert " at 0x" not in said, said


def _named(name: str, data: bytes) -> SimpleUploadedFile:
    return SimpleUploadedFile(name, data)
