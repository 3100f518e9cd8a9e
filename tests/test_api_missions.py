"""``/api/missions/``: starting missions and pausing, resuming, skipping and cancelling them."""

from __future__ import annotations

import pytest

from robots.models import Mission
from tests.conftest import client_for, make_robot, make_submap, map_pgm

pytestmark = pytest.mark.django_db

WAYPOINTS = [
    {"map": "CorridorA", "x": 1.0, "y": 2.0, "yaw": 0.5},
    {"map": "CorridorA", "x": 3, "y": 1},
]


@pytest.fixture
def robot(building):
    # 5 x 3 m, walled round, unknown in the top-left corner: waypoints are checked on it
    make_submap(building, code="CorridorA", image=map_pgm(width=100, height=60))
    robot, _ = make_robot(name="r1", buildings=[building])
    return robot


def start(user, **kwargs):
    kwargs.setdefault("building", "boccioni_1")
    kwargs.setdefault("robot", "r1")
    kwargs.setdefault("waypoints", WAYPOINTS)
    return client_for(user).post("/api/missions/", kwargs, format="json")


def test_an_operator_starts_a_patrol_that_every_operator_sees(operator, admin, robot):
    answer = start(operator, mode="patrol", name="night round")
    assert answer.status_code == 201, answer.json()
    mission = answer.json()
    assert (mission["state"], mission["index"], mission["mode"]) == ("running", 0, "patrol")
    assert mission["waypoints"][1] == {"map": "CorridorA", "x": 3.0, "y": 1.0, "yaw": 0.0}
    listed = client_for(admin).get("/api/missions/?building=boccioni_1&active=1").json()
    assert [m["id"] for m in listed] == [mission["id"]]


def test_a_new_mission_replaces_the_robots_active_one(operator, robot):
    first = start(operator).json()
    start(operator)
    assert Mission.objects.get(pk=first["id"]).state == "cancelled"


def test_waypoints_must_name_submaps_of_the_building(operator, robot):
    answer = start(operator, waypoints=[{"map": "Nowhere", "x": 1, "y": 1}])
    assert answer.status_code == 400
    assert "no sub-map 'Nowhere'" in answer.json()["mission"][0]
    assert start(operator, waypoints=[]).status_code == 400
    assert start(operator, waypoints=[{"map": "CorridorA", "x": "a", "y": 1}]).status_code == 400


def test_pause_resume_skip_and_cancel(operator, robot):
    mission = start(operator).json()
    client = client_for(operator)
    url = f"/api/missions/{mission['id']}/"
    assert client.post(url + "pause").json()["state"] == "paused"
    assert client.post(url + "resume").json()["state"] == "running"
    skipped = client.post(url + "skip").json()
    assert skipped["index"] == 1
    assert client.post(url + "skip").json()["state"] == "done"  # a single run ends
    assert client.post(url + "cancel").status_code == 400
    assert client.post(url + "launch").status_code == 404


def test_a_viewer_watches_but_runs_no_missions(viewer, operator, robot):
    assert start(viewer).status_code == 403
    mission = start(operator).json()
    assert client_for(viewer).post(f"/api/missions/{mission['id']}/pause").status_code == 403
    assert len(client_for(viewer).get("/api/missions/").json()) == 1


def test_it_rejects_outsider(outsider, operator, robot):
    start(operator)
    assert client_for(outsider).get("/api/missions/").status_code == 403


@pytest.mark.parametrize(
    ("point", "reason"),
    [
        ((0.02, 1.5), "in an obstacle"),
        ((0.1, 2.85), "in unknown space"),
        ((6.0, 1.0), "outside the map"),
    ],
)
def test_a_waypoint_no_robot_could_reach_is_refused_with_its_field(operator, robot, point, reason):
    x, y = point
    waypoints = [WAYPOINTS[0], {"map": "CorridorA", "x": x, "y": y}]
    answer = start(operator, waypoints=waypoints)
    assert answer.status_code == 400
    assert answer.json() == {
        "waypoints": [f"The waypoint 2 ({x:.2f}, {y:.2f}) is {reason}. (boccioni_1/CorridorA)"]
    }
    assert not Mission.objects.exists()
