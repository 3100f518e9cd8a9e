"""Recording over real sockets: what a robot publishes to a live daphne is what its MCAP
file holds, read back message by message with the ``mcap`` reader."""

from __future__ import annotations

import asyncio
import io
import json
import time

import httpx
import pytest
import websockets
from django.http import StreamingHttpResponse
from mcap.reader import make_reader
from mcap_ros1.decoder import DecoderFactory

from telemetry.recording import files
from tests.conftest import client_for, make_robot
from tests.fixtures_live import session_cookie
from tests.support.robot_messages import pose, scan

DEADLINE = 20.0
NS = 1_000_000_000


async def publish_all(url: str) -> None:
    async with websockets.connect(url) as ws:
        await ws.send(json.dumps({"op": "publish", "topic": "map_id", "msg": {"data": "b/Hall"}}))
        for i in range(20):
            await ws.send(json.dumps({"op": "publish", "topic": "pose", "msg": pose(i)}))
            await ws.send(json.dumps({"op": "publish", "topic": "scan", "msg": scan(i)}))
            # the camera is not in the default plan: it must not be recorded
            frame = {"format": "jpeg", "data": "AAEC"}
            await ws.send(
                json.dumps({"op": "publish", "topic": "camera/image/compressed", "msg": frame})
            )
        await ws.send(json.dumps({"op": "call_service", "id": "t", "service": "rosapi/get_time"}))
        while json.loads(await asyncio.wait_for(ws.recv(), 10)).get("id") != "t":
            pass


def finished_files(root, robot):
    deadline = time.monotonic() + DEADLINE
    while time.monotonic() < deadline:
        found = files.files_of(root, robot)
        if found and all(files.finished(f.path) for f in found):
            return found
        time.sleep(0.05)
    raise TimeoutError(f"no finished recording of {robot} within {DEADLINE} s")


def read_back(path):
    with open(path, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        got = [
            (channel.topic, schema.name, schema.encoding, channel.message_encoding, ros)
            for schema, channel, _m, ros in reader.iter_decoded_messages(log_time_order=False)
            if schema is not None
        ]
        return reader.get_header().profile, got


def without_events(got):
    return [item for item in got if item[0] != "/r1/events"]


@pytest.fixture
def token(building):
    return make_robot(name="r1", buildings=[building])[1]


async def test_what_a_robot_publishes_is_recorded_message_by_message(
    daphne_servers, token, tmp_path
):
    root = tmp_path / "recordings"
    server = daphne_servers.start(env={"CLOUDNAV_RECORDING_DIR": str(root)})
    await publish_all(server.rosbridge_url(token))
    # the robot has gone: its file is finished
    [recording] = await asyncio.to_thread(finished_files, root, "r1")
    profile, got = read_back(recording.path)
    got = without_events(got)  # the robot's events: see the test below
    assert profile == "ros1"
    assert [(t, s, e, m) for t, s, e, m, _ in got[:3]] == [
        ("/r1/map_id", "std_msgs/String", "ros1msg", "ros1"),
        ("/r1/pose", "geometry_msgs/PoseStamped", "ros1msg", "ros1"),
        ("/r1/scan", "sensor_msgs/LaserScan", "ros1msg", "ros1"),
    ]
    assert got[0][4].data == "b/Hall"
    poses = [ros for topic, *_rest, ros in got if topic == "/r1/pose"]
    scans = [ros for topic, *_rest, ros in got if topic == "/r1/scan"]
    assert len(got) == 41
    assert len(poses) == 20
    assert len(scans) == 20
    for i, (p, s) in enumerate(zip(poses, scans, strict=True)):
        sent = pose(i)
        assert (p.header.stamp.secs, p.header.stamp.nsecs) == (100 + i, i)
        assert p.header.frame_id == sent["header"]["frame_id"]
        assert (p.pose.position.x, p.pose.position.y) == (i * 0.5, -i)
        assert list(s.ranges) == [float(i), 2.0, 3.0]
        assert s.header.stamp.secs == 100 + i


ABORTED = {
    "header": {"stamp": {"sec": 0, "nanosec": 0}, "frame_id": ""},
    "status_list": [
        {"goal_id": {"id": "g7"}, "status": 4, "text": "no path to the dock"},
    ],
}


async def abort_a_goal(url: str) -> None:
    async with websockets.connect(url) as ws:
        await ws.send(json.dumps({"op": "publish", "topic": "pose", "msg": pose(0)}))
        await ws.send(json.dumps({"op": "publish", "topic": "nav_status", "msg": ABORTED}))
        await ws.send(json.dumps({"op": "call_service", "id": "t", "service": "rosapi/get_time"}))
        while json.loads(await asyncio.wait_for(ws.recv(), 10)).get("id") != "t":
            pass


def exported(user, url: str) -> bytes:
    response = client_for(user).get(url)
    assert response.status_code == 200
    assert isinstance(response, StreamingHttpResponse)
    return b"".join(response.streaming_content)


async def test_the_events_derived_for_a_robot_are_in_its_exported_recording(
    daphne_servers, token, tmp_path, settings, viewer
):
    root = tmp_path / "recordings"
    settings.CLOUDNAV_RECORDING_DIR = root  # the export below reads what the server wrote
    server = daphne_servers.start(env={"CLOUDNAV_RECORDING_DIR": str(root)})
    began = time.time()
    await abort_a_goal(server.rosbridge_url(token))
    await asyncio.to_thread(finished_files, root, "r1")
    url = f"/api/robots/r1/recording.mcap?start={began - 5}&end={time.time() + 5}"
    body = await asyncio.to_thread(exported, viewer, url)
    reader = make_reader(io.BytesIO(body), decoder_factories=[DecoderFactory()])
    events = [
        (schema.name, schema.encoding, message.log_time, ros)
        for schema, channel, message, ros in reader.iter_decoded_messages()
        if channel.topic == "/r1/events" and schema is not None
    ]
    assert [(name, encoding) for name, encoding, *_ in events] == [
        ("rosgraph_msgs/Log", "ros1msg")
    ] * 3
    kinds = [ros.name for *_, ros in events]
    assert kinds == ["robot_connected", "goal_aborted", "robot_disconnected"]
    _n, _e, log_time, aborted = events[1]
    assert aborted.level == aborted.ERROR
    assert aborted.msg == "r1: goal aborted: no path to the dock"
    assert "goal=g7" in aborted.topics
    assert "actor=robot:r1" in aborted.topics
    # stamped with the event's time, which is the message's log time
    assert aborted.header.stamp.secs * NS + aborted.header.stamp.nsecs == log_time
    assert began - 1 <= log_time / NS <= time.time()


async def test_an_export_holds_everything_recorded_up_to_the_request_while_the_robot_records(
    daphne_servers, token, tmp_path, viewer
):
    root = tmp_path / "recordings"
    server = daphne_servers.start(env={"CLOUDNAV_RECORDING_DIR": str(root)})
    cookie = (await asyncio.to_thread(session_cookie, viewer)).decode()
    began = time.time()
    async with websockets.connect(server.rosbridge_url(token)) as ws:
        for i in range(20):  # far less than a chunk: all of it is in the open chunk
            await ws.send(json.dumps({"op": "publish", "topic": "pose", "msg": pose(i)}))
        await ws.send(json.dumps({"op": "call_service", "id": "t", "service": "rosapi/get_time"}))
        while json.loads(await asyncio.wait_for(ws.recv(), 10)).get("id") != "t":
            pass
        url = f"{server.url}/api/robots/r1/recording.mcap?start={began - 5}&end={time.time() + 5}"
        async with httpx.AsyncClient(timeout=DEADLINE) as http:
            response = await http.get(url, headers={"Cookie": cookie})
        # the robot is still connected: its file is still being written
        assert not any(files.finished(f.path) for f in files.files_of(root, "r1"))
    assert response.status_code == 200
    reader = make_reader(io.BytesIO(response.content), decoder_factories=[DecoderFactory()])
    poses = [
        ros.pose.position.x
        for _s, channel, _m, ros in reader.iter_decoded_messages()
        if channel.topic == "/r1/pose"
    ]
    assert poses == [i * 0.5 for i in range(20)]


async def test_a_file_a_killed_server_was_writing_is_repaired_when_the_next_one_starts(
    daphne_servers, token, tmp_path, viewer
):
    root = tmp_path / "recordings"
    first = daphne_servers.start(env={"CLOUDNAV_RECORDING_DIR": str(root)})
    cookie = (await asyncio.to_thread(session_cookie, viewer)).decode()
    began = time.time()
    async with websockets.connect(first.rosbridge_url(token)) as ws:
        for i in range(20):
            await ws.send(json.dumps({"op": "publish", "topic": "pose", "msg": pose(i)}))
        await ws.send(json.dumps({"op": "call_service", "id": "t", "service": "rosapi/get_time"}))
        while json.loads(await asyncio.wait_for(ws.recv(), 10)).get("id") != "t":
            pass
        url = f"{first.url}/api/robots/r1/recording.mcap?start={began - 5}&end={time.time() + 5}"
        async with httpx.AsyncClient(timeout=DEADLINE) as http:  # the poses reach the file
            assert (await http.get(url, headers={"Cookie": cookie})).status_code == 200
        first.process.kill()  # kill -9 mid-file: no summary, no footer
        first.process.wait(10)
    [left] = files.files_of(root, "r1")
    assert not files.finished(left.path)
    second = daphne_servers.start(env={"CLOUDNAV_RECORDING_DIR": str(root)})
    async with websockets.connect(second.rosbridge_url(token)):  # its recorder starts
        deadline = time.monotonic() + DEADLINE
        while not files.finished(left.path):
            assert time.monotonic() < deadline, second.log()
            await asyncio.sleep(0.05)
    _profile, got = read_back(left.path)  # by its index
    poses = [ros.pose.position.x for topic, *_rest, ros in got if topic == "/r1/pose"]
    assert poses == [i * 0.5 for i in range(20)]
