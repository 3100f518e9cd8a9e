"""``/api/events/``, acknowledging alerts and the open-alert count."""

from __future__ import annotations

from datetime import UTC, datetime, timedelta

import pytest

from telemetry.models import Event
from tests.conftest import client_for, make_building, make_robot

pytestmark = pytest.mark.django_db

T0 = datetime(2026, 11, 24, 8, 0, tzinfo=UTC)


def make_event(**kwargs):
    kwargs.setdefault("time", T0)
    kwargs.setdefault("kind", "goal_aborted")
    kwargs.setdefault("severity", "error")
    kwargs.setdefault("message", "r1: goal aborted: no path")
    kwargs.setdefault("alert", True)
    return Event.objects.create(**kwargs)


@pytest.fixture
def events(building):
    robot, _ = make_robot(name="r1", buildings=[building])
    elsewhere = make_building(code="other_1")
    return [
        make_event(building=building, robot=robot),
        make_event(
            building=building,
            robot=robot,
            kind="robot_connected",
            severity="info",
            alert=False,
            time=T0 - timedelta(minutes=5),
        ),
        make_event(building=elsewhere, message="not yours"),
    ]


def test_people_see_the_events_of_their_buildings_newest_first(viewer, events):
    answer = client_for(viewer).get("/api/events/").json()
    assert [e["kind"] for e in answer] == ["goal_aborted", "robot_connected"]
    assert answer[0]["robot"] == "r1"
    assert answer[0]["building"] == "boccioni_1"


def test_events_filter_by_kind_robot_time_and_open_alerts(viewer, events):
    client = client_for(viewer)
    assert len(client.get("/api/events/?kind=robot_connected").json()) == 1
    assert len(client.get("/api/events/?robot=r1&alerts=open").json()) == 1
    since = (T0 - timedelta(minutes=1)).isoformat().replace("+00:00", "Z")
    assert len(client.get("/api/events/", {"since": since}).json()) == 1
    assert client.get("/api/events/?since=yesterday").status_code == 400


def test_an_operator_acknowledges_an_alert_and_it_is_no_longer_open(operator, events):
    client = client_for(operator)
    assert client.get("/api/alerts/open").json() == {"open": 1}
    answer = client.post(f"/api/events/{events[0].id}/acknowledge").json()
    assert answer["acknowledged_by"] == "operator"
    assert answer["acknowledged_at"]
    assert client.get("/api/alerts/open").json() == {"open": 0}
    assert client.get("/api/events/?alerts=open").json() == []


def test_a_cleared_alert_is_no_longer_open_but_stays_in_the_events(viewer, events):
    Event.objects.filter(pk=events[0].pk).update(cleared_at=T0 + timedelta(minutes=1))
    client = client_for(viewer)
    assert client.get("/api/alerts/open").json() == {"open": 0}
    assert client.get("/api/events/?alerts=open").json() == []
    [kept] = client.get("/api/events/?alerts=all").json()
    assert kept["cleared_at"].startswith("2026-11-24T08:01")


def test_a_viewer_may_not_acknowledge(viewer, events):
    assert client_for(viewer).post(f"/api/events/{events[0].id}/acknowledge").status_code == 403


def test_an_alert_of_another_building_is_not_found(operator, events):
    assert client_for(operator).post(f"/api/events/{events[2].id}/acknowledge").status_code == 404


def test_it_rejects_outsider(outsider, events):
    assert client_for(outsider).get("/api/events/").status_code == 403
    assert client_for(outsider).get("/api/alerts/open").status_code == 403


def test_it_rejects_robots(events):
    _, token = make_robot(name="r2")
    assert client_for(token).get("/api/events/").status_code == 403
