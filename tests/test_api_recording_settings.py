"""``/api/buildings/{code}/recording/``: a building's admins set what its robots record and
how long it is kept, in the app; members read it; nobody else reads or changes it."""

from __future__ import annotations

import pytest

from telemetry.models import DEFAULT_RECORDED, RecordingSettings
from telemetry.recording.plans import DEFAULT, NOTHING, Plan, plan_for, plans_for, retentions
from tests.conftest import client_for, make_building, make_robot, make_user

pytestmark = pytest.mark.django_db

URL = "/api/buildings/boccioni_1/recording/"
CHOICE = {
    "enabled": True,
    "topics": ["pose", "scan"],
    "camera_rate": 2.0,
    "retention_days": 3,
    "budget_mb": 500,
}


def test_a_building_that_never_chose_reads_the_defaults(viewer, building):
    answer = client_for(viewer).get(URL).json()
    assert sorted(answer["topics"]) == sorted(DEFAULT_RECORDED)
    assert (answer["enabled"], answer["camera_rate"], answer["retention_days"]) == (True, 0.0, 14)
    assert "battery" in answer["recordable"]
    assert not RecordingSettings.objects.exists()


def test_an_admin_sets_what_is_recorded_and_kept_and_the_recorder_follows(admin, building):
    make_robot(name="r1", buildings=[building])
    answer = client_for(admin).put(URL, CHOICE, format="json")
    assert answer.status_code == 200, answer.content
    assert {k: answer.json()[k] for k in CHOICE} == CHOICE
    plan = plan_for("r1")
    assert plan.topics == {"pose", "scan", "camera/image/compressed"}
    assert plan.camera_interval == pytest.approx(0.5)
    [kept] = [r for r in retentions() if r.building == "boccioni_1"]
    assert (kept.days, kept.budget) == (3, 500_000_000)


def test_an_admin_changes_one_setting_and_keeps_the_others(admin, building):
    client_for(admin).put(URL, CHOICE, format="json")
    answer = client_for(admin).patch(URL, {"enabled": False}, format="json").json()
    assert (answer["enabled"], answer["topics"], answer["retention_days"]) == (
        False,
        ["pose", "scan"],
        3,
    )


def test_bad_settings_get_field_errors_and_change_nothing(admin, building):
    client = client_for(admin)
    bad = {**CHOICE, "topics": ["pose", "no_such"], "camera_rate": 99, "retention_days": 0}
    answer = client.put(URL, bad, format="json")
    assert answer.status_code == 400
    assert set(answer.json()) >= {"topics", "camera_rate", "retention_days"}
    assert not RecordingSettings.objects.exists()
    assert client.patch(URL, {"budget_mb": "lots"}, format="json").status_code == 400


@pytest.mark.parametrize("persona", ["operator", "viewer"])
def test_it_rejects_operators_and_viewers_changing_it(persona, request, building):
    client = client_for(request.getfixturevalue(persona))
    assert client.put(URL, CHOICE, format="json").status_code == 403
    assert client.patch(URL, {"enabled": False}, format="json").status_code == 403
    assert not RecordingSettings.objects.exists()


def test_it_rejects_outsider(outsider, building):
    assert client_for(outsider).get(URL).status_code == 403
    assert client_for(outsider).patch(URL, {"enabled": False}, format="json").status_code == 403


def test_it_rejects_an_admin_of_another_building(building):
    stranger = make_user("stranger", "admin")
    assert client_for(stranger).get(URL).status_code == 404
    assert client_for(stranger).patch(URL, {"enabled": False}, format="json").status_code == 404


def test_it_rejects_robots(building, token):
    assert client_for(token).get(URL).status_code == 403
    assert client_for(token).patch(URL, {"enabled": False}, format="json").status_code == 403


def test_it_rejects_anonymous(building):
    assert client_for(None).get(URL).status_code in (401, 403)


def test_the_recorder_reads_every_robots_plan_in_two_queries(
    admin, building, django_assert_num_queries
):
    client_for(admin).put(URL, CHOICE, format="json")
    other = make_building(code="other_1")
    RecordingSettings.objects.create(building=other, topics=["odom"], camera_rate=5.0)
    make_robot(name="r1", buildings=[building])
    make_robot(name="both", buildings=[building, other])
    make_robot(name="nowhere", buildings=[])
    many = [f"r{i}" for i in range(2, 40)]
    for name in many:
        make_robot(name=name, buildings=[other])
    with django_assert_num_queries(2):
        plans = plans_for(["r1", "both", "nowhere", "unknown", *many])
    assert plans["r1"] == Plan(frozenset({"pose", "scan", "camera/image/compressed"}), 0.5)
    assert plans["both"].topics == {"pose", "scan", "odom", "camera/image/compressed"}
    assert plans["both"].camera_interval == pytest.approx(0.2)  # the fastest camera wins
    assert (plans["nowhere"], plans["unknown"]) == (DEFAULT, NOTHING)
    assert all(plans[name] == plans["r2"] for name in many)
    assert plans == {name: plan_for(name) for name in plans}
