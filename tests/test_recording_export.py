"""Export: any time range of a robot or a building as one MCAP file (or a ROS 1 bag)."""

from __future__ import annotations

import io
from pathlib import Path

import pytest
from mcap.reader import make_reader
from mcap_ros1.decoder import DecoderFactory
from rosbags.rosbag1 import Reader as BagReader

from maps.models import Building
from robots.models import Robot
from telemetry.domain import ros1, rosbag
from telemetry.domain.events import EVENT_TYPE, EventDraft, Kind, Severity, as_log
from telemetry.recording import export, files
from tests.conftest import client_for, make_building, make_robot

NS = 1_000_000_000
POSE = {"header": {"frame_id": "b/Hall"}, "pose": {"position": {"x": 1.0}}}


def record_poses(root: Path, robot: str, seconds: range) -> None:
    writer = files.RotatingFiles(root, robot, max_seconds=10, max_bytes=2**30)
    schema = ros1.schema_text("geometry_msgs/PoseStamped").encode()
    for second in seconds:
        msg = {**POSE, "pose": {"position": {"x": float(second)}}}
        data = ros1.encode("geometry_msgs/PoseStamped", msg)
        writer.write(
            files.Record(f"/{robot}/pose", "geometry_msgs/PoseStamped", schema, second * NS, data)
        )
    writer.close()


def read_mcap(body: bytes) -> list[tuple[str, int, float]]:
    reader = make_reader(io.BytesIO(body), decoder_factories=[DecoderFactory()])
    return [
        (channel.topic, message.log_time // NS, ros.pose.position.x)
        for _s, channel, message, ros in reader.iter_decoded_messages()
    ]


@pytest.fixture
def recordings(settings, tmp_path, building):
    settings.CLOUDNAV_RECORDING_DIR = tmp_path
    robot, _token = make_robot(name="r1")
    robot.buildings.add(building)
    other, _ = make_robot(name="r2")
    other.buildings.add(building)
    record_poses(tmp_path, "r1", range(1000, 1100, 2))
    record_poses(tmp_path, "r2", range(1001, 1100, 2))
    return tmp_path


def body_of(response) -> bytes:
    assert response.streaming
    return b"".join(response.streaming_content)


def test_it_streams_a_robots_range_in_unix_seconds(recordings, viewer):
    response = client_for(viewer).get("/api/robots/r1/recording.mcap?start=1010&end=1020")
    assert response.status_code == 200
    assert response["Content-Type"] == "application/mcap"
    assert "r1-1010-1020.mcap" in response["Content-Disposition"]
    messages = read_mcap(body_of(response))
    assert messages == [("/r1/pose", s, float(s)) for s in range(1010, 1021, 2)]


def test_it_takes_iso_8601_times(recordings, viewer):
    url = "/api/robots/r1/recording.mcap?start=1970-01-01T00:16:50Z&end=1970-01-01T00:17:00"
    response = client_for(viewer).get(url)
    assert [m[1] for m in read_mcap(body_of(response))] == list(range(1010, 1021, 2))


def test_a_building_export_merges_its_robots_in_time_order(recordings, viewer):
    response = client_for(viewer).get(
        "/api/buildings/boccioni_1/recording.mcap?start=1010&end=1015"
    )
    assert read_mcap(body_of(response)) == [
        ("/r1/pose", 1010, 1010.0),
        ("/r2/pose", 1011, 1011.0),
        ("/r1/pose", 1012, 1012.0),
        ("/r2/pose", 1013, 1013.0),
        ("/r1/pose", 1014, 1014.0),
        ("/r2/pose", 1015, 1015.0),
    ]


def test_a_range_without_data_is_a_valid_empty_file(recordings, viewer):
    response = client_for(viewer).get("/api/robots/r1/recording.mcap?start=5000&end=6000")
    assert response.status_code == 200
    assert read_mcap(body_of(response)) == []


def test_it_answers_400_naming_the_field_for_bad_times(recordings, viewer):
    client = client_for(viewer)
    response = client.get("/api/robots/r1/recording.mcap?start=yesterday")
    assert response.status_code == 400
    assert "start" in response.json()
    response = client.get("/api/robots/r1/recording.mcap?start=20&end=10")
    assert response.status_code == 400
    assert "start" in response.json()


def test_it_rejects_outsider(recordings, outsider):
    client = client_for(outsider)
    assert client.get("/api/robots/r1/recording.mcap").status_code == 404
    assert client.get("/api/buildings/boccioni_1/recording.mcap").status_code == 404
    assert client_for(None).get("/api/robots/r1/recording.mcap").status_code in (401, 403)


def test_a_robot_of_another_building_is_not_found(recordings, viewer):
    hidden, _ = make_robot(name="r3")
    hidden.buildings.add(make_building(code="elsewhere"))
    assert client_for(viewer).get("/api/robots/r3/recording.mcap").status_code == 404


def test_rosbags_opens_the_ros1_bag_export(recordings, viewer, tmp_path):
    response = client_for(viewer).get("/api/robots/r1/recording.bag?start=1010&end=1014")
    assert response.status_code == 200
    path = tmp_path / "out.bag"
    path.write_bytes(body_of(response))
    with BagReader(path) as bag:
        [connection] = bag.connections
        assert (connection.topic, connection.msgtype) == (
            "/r1/pose",
            "geometry_msgs/msg/PoseStamped",
        )
        read = [
            (t // NS, ros1.decode("geometry_msgs/PoseStamped", raw).pose.position.x)
            for _c, t, raw in bag.messages()
        ]
    assert read == [(1010, 1010.0), (1012, 1012.0), (1014, 1014.0)]
    assert not list((recordings / ".exports").glob("*.bag"))


def test_a_huge_range_is_streamed_in_pieces(tmp_path, monkeypatch):
    monkeypatch.setattr(export, "EXPORT_CHUNK_BYTES", 16 * 1024)
    record_poses(tmp_path, "r1", range(0, 5000))
    pieces = export.mcap_stream(export.records(tmp_path, ["r1"], 0, 10**12 * NS))
    sizes = [len(p) for p in pieces]
    assert len(sizes) > 1
    assert max(sizes) < 2 * export.EXPORT_CHUNK_BYTES


def test_the_replay_window_is_rosbridge_json_with_its_span(recordings, viewer):
    url = "/api/robots/r1/recording.json?start=1010&end=1016&topics=pose&limit=3"
    body = client_for(viewer).get(url).json()
    assert body["span"][0] == 1000.0
    assert [m["t"] for m in body["messages"]] == [1010.0, 1012.0, 1014.0]
    assert body["messages"][0]["topic"] == "/r1/pose"
    assert body["messages"][0]["msg"]["pose"]["position"]["x"] == 1010.0
    assert body["messages"][0]["msg"]["header"]["frame_id"] == "b/Hall"
    assert body["more"] is True
    assert body["next"] == 1016.0
    assert (
        client_for(viewer).get(url.replace("topics=pose", "topics=scan")).json()["messages"] == []
    )


def test_the_replay_window_rejects_outsider(recordings, outsider):
    assert client_for(outsider).get("/api/robots/r1/recording.json").status_code == 404


def test_a_bag_of_many_chunks_and_robots_streams_in_pieces_that_rosbags_reads(tmp_path):
    record_poses(tmp_path, "r1", range(0, 3000, 2))
    record_poses(tmp_path, "r2", range(1, 3000, 2))
    taken = export.snapshot(tmp_path, ["r1", "r2"], 0, 10**12 * NS)
    sent = list(export.snapshot_records(taken, 0, 10**12 * NS))
    pieces = list(
        rosbag.bag_stream(lambda: export.snapshot_records(taken, 0, 10**12 * NS), 16 * 1024)
    )
    assert len(pieces) > 10  # the header, then a chunk at a time, then the index
    assert max(len(p) for p in pieces) < 32 * 1024
    path = tmp_path / "out.bag"
    path.write_bytes(b"".join(pieces))
    with BagReader(path) as bag:
        assert sorted(c.topic for c in bag.connections) == ["/r1/pose", "/r2/pose"]
        assert len(bag.chunk_infos) > 10
        read = [(c.topic, t, bytes(raw)) for c, t, raw in bag.messages()]
    assert read == [(r.topic, r.log_time, r.data) for r in sent]
    assert [t // NS for _topic, t, _raw in read] == list(range(3000))


def test_a_bag_is_never_written_from_two_different_readings():
    first = [files.Record("/r1/pose", "geometry_msgs/PoseStamped", b"", 1, b"a")]
    readings = iter([first, [*first, first[0]]])
    with pytest.raises(rosbag.BagSourceChanged):
        b"".join(rosbag.bag_stream(lambda: next(readings)))


def test_a_snapshot_of_a_file_being_written_reads_the_same_after_it_grew(tmp_path):
    writer = files.RotatingFiles(tmp_path, "r1", max_seconds=3600, max_bytes=2**30)
    schema = ros1.schema_text("geometry_msgs/PoseStamped").encode()
    data = ros1.encode("geometry_msgs/PoseStamped", POSE)

    def write(second: int) -> None:
        record = files.Record("/r1/pose", "geometry_msgs/PoseStamped", schema, second * NS, data)
        writer.write(record)

    for second in range(10):
        write(second)
    writer.flush()
    taken = export.snapshot(tmp_path, ["r1"], 0, 10**6 * NS)
    before = [r.log_time for r in export.snapshot_records(taken, 0, 10**6 * NS)]
    for second in range(10, 20):
        write(second)
    writer.flush()
    after = [r.log_time for r in export.snapshot_records(taken, 0, 10**6 * NS)]
    writer.close()
    assert before == after == [s * NS for s in range(10)]
    assert len(list(export.records(tmp_path, ["r1"], 0, 10**6 * NS))) == 20


def record_goal_event(root: Path, robot: str, second: int) -> None:
    """An event the server derived: ``operator`` sent the robot a goal."""
    text = f"operator sent {robot} a goal"
    draft = EventDraft(second, Kind.GOAL_SENT, Severity.INFO, robot, text, "user:operator")
    writer = files.RotatingFiles(root, robot, max_seconds=10, max_bytes=2**30)
    data = ros1.encode(EVENT_TYPE, as_log(draft))
    schema = ros1.schema_text(EVENT_TYPE).encode()
    writer.write(files.Record(f"/{robot}/events", EVENT_TYPE, schema, second * NS, data))
    writer.close()


def read_back(kind: str, response, tmp_path: Path) -> list[tuple[str, bytes]]:
    """Each message of an export or a replay window: its topic and its raw content."""
    assert response.status_code == 200
    if kind == "json":
        return [(m["topic"], str(m["msg"]).encode()) for m in response.json()["messages"]]
    if kind == "mcap":
        reader = make_reader(io.BytesIO(body_of(response)))
        return [(c.topic, m.data) for _s, c, m in reader.iter_messages()]
    path = tmp_path / "read.bag"
    path.write_bytes(body_of(response))
    with BagReader(path) as bag:
        return [(c.topic, bytes(raw)) for c, _t, raw in bag.messages()]


@pytest.mark.parametrize("kind", ["mcap", "bag", "json"])
def test_a_robot_reads_its_own_recording_without_peoples_names(recordings, viewer, kind, tmp_path):
    token = make_robot(name="r3", buildings=[make_building(code="b3")])[1]
    record_poses(recordings, "r3", range(1000, 1010, 2))
    record_goal_event(recordings, "r3", 1005)
    url = f"/api/robots/r3/recording.{kind}?start=1000&end=1010"
    mine = read_back(kind, client_for(token).get(url), tmp_path)
    assert {topic for topic, _ in mine} == {"/r3/pose"}
    assert not any(b"operator" in content for _, content in mine)
    # the building's people read the events, with who did what
    Robot.objects.get(name="r3").buildings.add(Building.objects.get(code="boccioni_1"))
    theirs = read_back(kind, client_for(viewer).get(url), tmp_path)
    events = [content for topic, content in theirs if topic == "/r3/events"]
    assert len(events) == 1
    assert b"operator sent r3 a goal" in events[0]
