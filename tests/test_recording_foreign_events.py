"""Events a robot's process did not derive itself (another server process's, a request's)
reach its recording from the event log: a bundle fetched, a new map version, a goal sent
from another process."""

from __future__ import annotations

from pathlib import Path

from telemetry.domain import events as derived
from telemetry.domain import ros1
from telemetry.domain.events import EventDraft, Kind, Severity
from telemetry.events import ORIGIN, foreign_events, write_events
from telemetry.models import Event
from telemetry.recording import files
from telemetry.recording.plans import DEFAULT
from telemetry.recording.recorder import Recorder, RecorderConfig
from tests.conftest import client_for, make_building, make_robot, make_submap

BUNDLE = "/api/buildings/{code}/maps/CorridorA/bundle"


def goal_sent(robot: str, t: float) -> EventDraft:
    return EventDraft(t, Kind.GOAL_SENT, Severity.INFO, robot, "sent", "user:op", "b")


def recorded_kinds(root: Path, robot: str) -> list[str]:
    found = [r for f in files.files_of(root, robot) for r in files.open_messages(f.path, 0, 2**62)]
    return [ros1.decode(r.type_name, r.data).name for r in found if r.topic.endswith("/events")]


def test_the_recorder_takes_the_events_others_wrote_for_its_robots_once(db, tmp_path):
    building = make_building(code="b")
    make_robot(name="r1", buildings=[building])
    make_robot(name="r2", buildings=[building])
    write_events([goal_sent("r1", 1.0)], origin="before")  # older than the recorder: not its
    config = RecorderConfig(root=tmp_path, events_seconds=0.0)
    recorder = Recorder(
        config,
        lambda robots: dict.fromkeys(robots, DEFAULT),
        lambda: [],
        foreign_events=foreign_events,
    )
    recorder.connected("r1")
    recorder.step()
    write_events([goal_sent("r1", 2.0)], origin="another-process")
    write_events([goal_sent("r1", 2.5)], origin=ORIGIN)  # this process's own: told directly
    write_events([goal_sent("r2", 3.0)], origin="another-process")  # r2 is not here
    version = derived.map_version_changed("b", "b/Hall", 2, "upload", "user:ann", 4.0)
    write_events([version])  # a building's event: once for each of its robots here
    recorder.step()
    recorder.step()  # nothing read twice
    recorder.disconnected("r1")
    recorder.step()
    assert recorded_kinds(tmp_path, "r1") == ["goal_sent", "map_version_changed"]
    assert files.files_of(tmp_path, "r2") == []


def test_a_robot_fetching_a_bundle_and_a_new_version_are_events(
    db, django_capture_on_commit_callbacks
):
    building = make_building(code="b")
    with django_capture_on_commit_callbacks(execute=True):
        make_submap(building)
    _robot, token = make_robot(name="r1", buildings=[building])
    with django_capture_on_commit_callbacks(execute=True):
        response = client_for(token).get(BUNDLE.format(code="b"))
    assert response.status_code == 200
    with django_capture_on_commit_callbacks(execute=True):
        again = client_for(token).get(BUNDLE.format(code="b"), HTTP_IF_NONE_MATCH=response["ETag"])
    assert again.status_code == 304  # not fetched again: no event
    rows = list(Event.objects.order_by("id"))
    assert [(e.kind, e.robot and e.robot.name, e.building and e.building.code) for e in rows] == [
        ("map_version_changed", None, "b"),
        ("bundle_fetched", "r1", "b"),
    ]
    assert rows[0].data["map_id"] == "b/CorridorA"
    assert rows[1].actor == "robot:r1"
    assert all(e.origin == "" for e in rows)
