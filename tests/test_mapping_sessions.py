"""Mapping sessions through the API and the runner: start, live map, finish, publish as a
sub-map or a new version; bad requests and faults (an offline robot, two sessions on one
robot, a robot that disconnects mid-session, a publish on a version no longer current)."""

from __future__ import annotations

import json
import math
from typing import Any

import pytest
from asgiref.sync import sync_to_async
from django.contrib.auth.models import User

from cloudnav_core.messages import pose_2d
from maps.mapping import runner as mapping_runner
from maps.mapping.runner import MappingRunner
from maps.models import Building, MappingSession, SubMap
from robots.models import Robot
from tests.conftest import FakeHub, client_for, make_robot, make_submap
from tests.support.mapping_sessions import _drained, _session, _until, online, tour_messages, toured

SESSIONS = "/api/mapping/sessions/"
UNMAPPED = "/r1/camera/depth/image/compressedDepth"
"""The one tap on a robot with no session: its first depth frame is answered (not_mapping)."""


@pytest.fixture
def robot(building: Building) -> Robot:
    return make_robot(name="r1", buildings=[building])[0]


def start(user: User, **body: Any) -> Any:
    body.setdefault("robot", "r1")
    body.setdefault("building", "boccioni_1")
    body.setdefault("code", "RoomX")
    return client_for(user).post(SESSIONS, body, format="json")


def test_a_session_for_an_offline_robot_is_refused(robot: Robot, operator: User) -> None:
    answer = start(operator)
    assert answer.status_code == 409
    assert "offline" in answer.json()["detail"]


def test_two_sessions_on_one_robot_are_refused(robot: Robot, operator: User) -> None:
    online(robot)
    assert start(operator).status_code == 201
    second = start(operator, code="RoomY")
    assert second.status_code == 409
    assert "already has a mapping session" in second.json()["detail"]


def test_a_new_code_must_be_new_and_an_update_must_exist(
    robot: Robot, operator: User, building: Building
) -> None:
    online(robot)
    make_submap(building, code="CorridorA")
    assert "exists" in start(operator, code="CorridorA").json()["detail"]
    assert "no sub-map" in start(operator, code="Nowhere", update=True).json()["detail"]
    answer = start(operator, code="CorridorA", update=True)
    assert answer.status_code == 201
    assert answer.json()["based_on"] == 1


def test_viewers_may_not_start_and_outsiders_see_nothing(
    robot: Robot, viewer: User, outsider: User, operator: User
) -> None:
    online(robot)
    assert start(viewer).status_code == 403
    assert start(outsider).status_code == 404
    pk = start(operator).json()["id"]
    assert client_for(outsider).get(f"{SESSIONS}{pk}/").status_code == 404
    assert client_for(outsider).get(SESSIONS).json() == []
    assert client_for(viewer).post(f"{SESSIONS}{pk}/finish").status_code == 403


def test_it_rejects_outsider(robot: Robot, outsider: User, operator: User) -> None:
    online(robot)
    pk = start(operator).json()["id"]
    for path in ("", "grid", "candidate.zip"):
        assert client_for(outsider).get(f"{SESSIONS}{pk}/{path}").status_code == 404
    assert client_for(outsider).post(f"{SESSIONS}{pk}/publish").status_code == 404


def test_scans_beyond_the_queue_drop_the_oldest() -> None:
    session = MappingSession(pk=1, robot=Robot(name="r1"), start_x=0, start_y=0, start_yaw=0)
    worker = mapping_runner.LaserWorker(session)
    for index in range(100):
        worker.on_scan({"index": index})
    assert len(worker.queue) == mapping_runner.QUEUE_SCANS
    assert worker.dropped == 100 - mapping_runner.QUEUE_SCANS
    assert worker.queue[0][1] == {"index": 100 - mapping_runner.QUEUE_SCANS}


@pytest.mark.django_db(transaction=True)
async def test_a_robot_maps_a_room_and_an_admin_publishes_it(monkeypatch) -> None:
    monkeypatch.setattr(mapping_runner, "SAVE_EVERY", 0.2)
    session, admin, building = await sync_to_async(_mapping_setup)()
    client = await sync_to_async(client_for)(admin)
    messages = tour_messages()
    hub = FakeHub("r1")
    told: list[tuple[str, str]] = []
    runner = MappingRunner(hub, tell=lambda name, msg: told.append((name, msg["data"])))
    await runner.sync()
    assert set(hub.taps) == {"/r1/scan", "/r1/odom"}
    worker = runner.workers[session.pk]
    for index, (odom, scan) in enumerate(messages):
        hub.send("/r1/odom", odom)
        if index == 50:
            scan = {**scan, "ranges": [None] * len(scan["ranges"])}  # a scan of nothing
        hub.send("/r1/scan", scan)
        await _drained(worker)
    await _until(lambda: _session(session.pk).stats.get("matched", 0) > 100)
    live = await sync_to_async(_session)(session.pk)
    assert live.stats["dropped"] == 0
    assert live.stats["skipped"] == 1
    assert live.snapshot >= 1
    assert len(live.path) > 50
    grid = await sync_to_async(client.get)(f"{SESSIONS}{session.pk}/grid")
    assert grid.json()["info"]["width"] > 50

    finished = await sync_to_async(client.post)(f"{SESSIONS}{session.pk}/finish")
    assert finished.json()["state"] == "finished"
    await runner.sync()
    assert set(hub.taps) == {UNMAPPED}  # only to tell it, should it stream with no session
    # pages were told as the session started, saved its map and stopped (no polling)
    said = [json.loads(data) for name, data in told if name == "/r1/mapping"]
    events = [news["event"] for news in said]
    assert events[0] == "started"
    assert events[-1] == "stopped"
    assert "saved" in events
    assert {news["session"] for news in said} == {session.pk}
    published = await sync_to_async(client.post)(
        f"{SESSIONS}{session.pk}/publish", {"note": "the new room"}, format="json"
    )
    assert published.status_code == 201
    assert (published.json()["number"], published.json()["reason"]) == (1, "mapping")
    made = await SubMap.objects.aget(building=building, code="RoomX")
    assert made.width > 50


@pytest.mark.django_db(transaction=True)
async def test_a_robot_that_disconnects_leaves_its_partial_map_to_resume_or_discard(
    monkeypatch,
) -> None:
    monkeypatch.setattr(mapping_runner, "SAVE_EVERY", 0.2)
    session, admin, _ = await sync_to_async(_mapping_setup)()
    client = await sync_to_async(client_for)(admin)
    messages = tour_messages()
    hub = FakeHub("r1")
    runner = MappingRunner(hub)
    await runner.sync()
    for odom, scan in messages[:200]:
        hub.send("/r1/odom", odom)
        hub.send("/r1/scan", scan)
        await _drained(runner.workers[session.pk])
    await _until(lambda: _session(session.pk).stats.get("matched", 0) > 20)
    hub.here.clear()  # the robot went away
    await runner.sync()
    kept = await sync_to_async(_session)(session.pk)
    assert kept.state == "interrupted"
    assert "disconnected" in kept.reason
    assert kept.grid_pgm
    assert kept.keyframes

    hub.here.add("r1")
    resumed = await sync_to_async(client.post)(f"{SESSIONS}{session.pk}/resume")
    assert resumed.json()["state"] == "running"
    await runner.sync()
    worker = runner.workers[session.pk]
    assert isinstance(worker, mapping_runner.LaserWorker)
    assert len(worker.mapper.keyframes) == kept.stats["keyframes"]
    for odom, scan in messages[200:300]:
        hub.send("/r1/odom", odom)
        hub.send("/r1/scan", scan)
        await _drained(worker)
    await _until(lambda: _session(session.pk).stats.get("keyframes", 0) > kept.stats["keyframes"])
    assert math.dist(worker.mapper.pose[:2], (0, 0)) > 1  # placed where the robot is
    discarded = await sync_to_async(client.post)(f"{SESSIONS}{session.pk}/discard")
    assert discarded.json()["state"] == "discarded"
    again = await sync_to_async(client.post)(f"{SESSIONS}{session.pk}/resume")
    assert again.status_code == 409
    await runner.sync()
    assert runner.workers == {}


@pytest.mark.django_db(transaction=True)
async def test_publishing_an_update_made_on_an_old_version_is_refused(monkeypatch) -> None:
    session, admin, _ = await sync_to_async(_update_setup)()
    client = await sync_to_async(client_for)(admin)
    answer = await sync_to_async(client.post)(f"{SESSIONS}{session.pk}/publish")
    assert answer.status_code == 409
    assert answer.json()["based_on"] == 1
    assert answer.json()["current"] == 2
    assert (await sync_to_async(_session)(session.pk)).state == "finished"  # nothing lost


def _mapping_setup() -> tuple[MappingSession, User, Building]:
    from tests.conftest import make_building, make_user

    admin = make_user("admin", "admin")
    building = make_building(members=[admin])
    robot = make_robot(name="r1", buildings=[building])[0]
    online(robot)
    from maps.mapping import sessions

    start_pose = toured(0)[0].truth
    session = sessions.start(robot, building, "RoomX", admin)
    MappingSession.objects.filter(pk=session.pk).update(
        start_x=start_pose[0], start_y=start_pose[1], start_yaw=start_pose[2]
    )
    return session, admin, building


def _update_setup() -> tuple[MappingSession, User, Building]:
    from maps import versions
    from maps.mapping import sessions
    from tests.conftest import make_building, make_user

    admin = make_user("admin", "admin")
    building = make_building(members=[admin])
    robot = make_robot(name="r1", buildings=[building])[0]
    online(robot)
    corridor = make_submap(building, code="CorridorA")
    session = sessions.start(robot, building, "CorridorA", admin, update=True)
    MappingSession.objects.filter(pk=session.pk).update(
        grid_pgm=bytes(corridor.image), state="finished", origin_x=0.0, origin_y=0.0
    )
    versions.rollback(corridor, 1)  # the sub-map moves on to version 2 meanwhile
    return MappingSession.objects.get(pk=session.pk), admin, building


@pytest.mark.django_db(transaction=True)
async def test_a_bad_scan_is_refused_and_the_worker_keeps_mapping(monkeypatch) -> None:
    monkeypatch.setattr(mapping_runner, "SAVE_EVERY", 0.2)
    session, _, _ = await sync_to_async(_mapping_setup)()
    messages = tour_messages()
    hub = FakeHub("r1")
    runner = MappingRunner(hub)
    await runner.sync()
    worker = runner.workers[session.pk]
    for index, (odom, scan) in enumerate(messages[:120]):
        hub.send("/r1/odom", odom)
        if index == 10:
            scan = {**scan, "ranges": [{"a": 1}, *scan["ranges"][1:]]}
        hub.send("/r1/scan", scan)
        await _drained(worker)
    await _until(lambda: _session(session.pk).stats.get("matched", 0) > 20)
    live = await sync_to_async(_session)(session.pk)
    assert live.stats["bad_scans"] == 1
    assert "not all numbers" in live.stats["refusal"]
    assert live.state == "running"
    assert not worker.stopped


@pytest.mark.django_db(transaction=True)
async def test_odometry_far_outside_the_session_is_refused_said_and_costs_nothing(
    monkeypatch,
) -> None:
    monkeypatch.setattr(mapping_runner, "SAVE_EVERY", 0.2)
    session, admin, _ = await sync_to_async(_mapping_setup)()
    client = await sync_to_async(client_for)(admin)
    messages = tour_messages()
    hub = FakeHub("r1")
    runner = MappingRunner(hub)
    await runner.sync()
    worker = runner.workers[session.pk]
    far = {"pose": {"pose": pose_2d(600.0, 600.0, 0.0)}}
    for index, (odom, scan) in enumerate(messages[:120]):
        hub.send("/r1/odom", far if 60 <= index < 80 else odom)
        hub.send("/r1/scan", scan)
        await _drained(worker)
    await _until(lambda: _session(session.pk).stats.get("refused", 0) == 20)
    live = await sync_to_async(_session)(session.pk)
    assert "a session maps within 50 m" in live.stats["refusal"]
    width, height = (await sync_to_async(client.get)(f"{SESSIONS}{session.pk}/")).json()["size"]
    assert width * height < 1000 * 1000
    grid = await sync_to_async(client.get)(f"{SESSIONS}{session.pk}/grid")
    assert grid.status_code == 200
    assert len(grid.content) < 4 * 2**20


@pytest.mark.django_db(transaction=True)
async def test_a_session_with_no_keyframe_at_its_first_save_keeps_running(monkeypatch) -> None:
    monkeypatch.setattr(mapping_runner, "SAVE_EVERY", 0.2)
    session, admin, _ = await sync_to_async(_mapping_setup)()
    client = await sync_to_async(client_for)(admin)
    hub = FakeHub("r1")
    runner = MappingRunner(hub)
    await runner.sync()
    worker = runner.workers[session.pk]
    odom, scan = tour_messages()[0]
    hub.send("/r1/odom", odom)
    hub.send("/r1/scan", {**scan, "ranges": [None] * len(scan["ranges"])})
    await _until(lambda: _session(session.pk).stats.get("skipped", 0) == 1)
    assert not worker.stopped
    grid = await sync_to_async(client.get)(f"{SESSIONS}{session.pk}/grid")
    assert grid.status_code == 409
    assert "No map yet" in grid.json()["detail"]
    await runner.sync()
    assert (await sync_to_async(_session)(session.pk)).state == "running"


@pytest.mark.django_db(transaction=True)
async def test_a_session_whose_worker_stops_says_so() -> None:
    session, _, _ = await sync_to_async(_mapping_setup)()
    hub = FakeHub("r1")
    runner = MappingRunner(hub)
    await runner.sync()
    worker = runner.workers[session.pk]
    assert worker._task is not None
    worker._task.cancel()  # whatever ended it: the session must not stay "running"
    await _until(lambda: worker.stopped)
    await runner.sync()
    stopped = await sync_to_async(_session)(session.pk)
    assert stopped.state == "interrupted"
    assert "mapping stopped" in stopped.reason
    assert runner.workers == {}
    assert set(hub.taps) == {UNMAPPED}
