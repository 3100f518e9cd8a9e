"""Scaled mode: a robot is recorded once, by the process it is connected to, even when
its topics also reach the other process (a viewer there subscribes to them)."""

from __future__ import annotations

import asyncio
import io
import json
import time

import httpx
import pytest
import websockets
from mcap.reader import make_reader
from mcap_ros1.decoder import DecoderFactory

from telemetry.recording import files

pytestmark = pytest.mark.scaled

POSE = {"header": {"frame_id": "boccioni_1/Hall"}, "pose": {"position": {"x": 1, "y": 2}}}
DEADLINE = 20.0


async def receive(socket, wait=5.0):
    return json.loads(await asyncio.wait_for(socket.recv(), wait))


async def sync(socket):
    await socket.send(
        json.dumps({"op": "call_service", "id": "sync", "service": "/rosapi/get_time"})
    )
    while (await receive(socket)).get("id") != "sync":
        pass


def finished_files(root, robot):
    deadline = time.monotonic() + DEADLINE
    while time.monotonic() < deadline:
        found = files.files_of(root, robot)
        if found and all(files.finished(f.path) for f in found):
            return found
        time.sleep(0.05)
    raise TimeoutError(f"no finished recording of {robot} within {DEADLINE} s")


async def test_a_robot_is_recorded_once_by_the_process_it_is_connected_to(scaled_servers, tmp_path):
    root = tmp_path / "recordings"
    cluster = scaled_servers(2, env={"CLOUDNAV_RECORDING_DIR": str(root)})
    here, there = cluster.servers
    headers = {"Cookie": cluster.cookies["operator"], "Origin": there.url}
    async with websockets.connect(there.rosbridge_url(), additional_headers=headers) as viewer:
        await viewer.send(json.dumps({"op": "subscribe", "topic": "/r1/pose"}))
        await sync(viewer)
        async with websockets.connect(here.rosbridge_url(cluster.tokens["r1"])) as robot:
            for i in range(10):
                msg = {**POSE, "pose": {"position": {"x": i, "y": 2}}}
                await robot.send(json.dumps({"op": "publish", "topic": "pose", "msg": msg}))
            for _ in range(10):  # the other process relayed every one
                assert (await receive(viewer))["topic"] == "/r1/pose"
    recorded = await asyncio.to_thread(finished_files, root, "r1")
    assert len(recorded) == 1
    poses = list(files.open_messages(recorded[0].path, 0, 2**62))
    # with its arrival and its leaving, recorded once too
    assert [r.topic for r in poses] == ["/r1/events", *["/r1/pose"] * 10, "/r1/events"]


async def exported_events(server, cookie: str, began: float) -> list:
    url = f"{server.url}/api/robots/r1/recording.mcap?start={began - 5}&end={time.time() + 5}"
    async with httpx.AsyncClient(timeout=DEADLINE) as http:
        response = await http.get(url, headers={"Cookie": cookie})
    assert response.status_code == 200
    reader = make_reader(io.BytesIO(response.content), decoder_factories=[DecoderFactory()])
    return [
        ros
        for _s, channel, _m, ros in reader.iter_decoded_messages()
        if channel.topic == "/r1/events"
    ]


async def test_a_goal_sent_from_another_process_is_in_the_robots_recording(
    scaled_servers, tmp_path
):
    root = tmp_path / "recordings"
    cluster = scaled_servers(2, env={"CLOUDNAV_RECORDING_DIR": str(root)})
    here, there = cluster.servers
    cookie = cluster.cookies["operator"]
    began = time.time()
    async with websockets.connect(here.rosbridge_url(cluster.tokens["r1"])) as robot:
        await sync(robot)
        headers = {"Cookie": cookie, "Origin": there.url}
        async with websockets.connect(there.rosbridge_url(), additional_headers=headers) as op:
            # Inside the seeded 2 x 1.5 m Hall: goals are checked against their sub-map.
            goal = {
                "header": {"frame_id": "boccioni_1/Hall"},
                "pose": {"position": {"x": 1, "y": 0.75}},
            }
            advertise = {
                "op": "advertise",
                "topic": "/r1/goal",
                "type": "geometry_msgs/PoseStamped",
            }
            await op.send(json.dumps(advertise))
            await op.send(json.dumps({"op": "publish", "topic": "/r1/goal", "msg": goal}))
            await sync(op)
        # the robot's process records it, read from the event log the other one wrote
        deadline = time.monotonic() + DEADLINE
        while True:
            events = await exported_events(here, cookie, began)
            sent = [e for e in events if e.name == "goal_sent"]
            if sent or time.monotonic() > deadline:
                break
            await asyncio.sleep(0.2)
    assert len(sent) == 1
    assert "actor=user:operator" in sent[0].topics
    assert "map_id=boccioni_1/Hall" in sent[0].topics


async def test_an_export_from_another_process_holds_what_the_robots_process_still_held(
    scaled_servers, tmp_path
):
    root = tmp_path / "recordings"
    cluster = scaled_servers(2, env={"CLOUDNAV_RECORDING_DIR": str(root)})
    here, there = cluster.servers
    began = time.time()
    async with websockets.connect(here.rosbridge_url(cluster.tokens["r1"])) as robot:
        for i in range(20):  # far less than a chunk: all of it in the open chunk, here
            msg = {**POSE, "pose": {"position": {"x": i, "y": 2}}}
            await robot.send(json.dumps({"op": "publish", "topic": "pose", "msg": msg}))
        await sync(robot)
        url = f"{there.url}/api/robots/r1/recording.mcap?start={began - 5}&end={time.time() + 5}"
        async with httpx.AsyncClient(timeout=DEADLINE) as http:
            response = await http.get(url, headers={"Cookie": cluster.cookies["operator"]})
        assert not any(files.finished(f.path) for f in files.files_of(root, "r1"))
    assert response.status_code == 200
    reader = make_reader(io.BytesIO(response.content), decoder_factories=[DecoderFactory()])
    xs = [
        ros.pose.position.x
        for _s, channel, _m, ros in reader.iter_decoded_messages()
        if channel.topic == "/r1/pose"
    ]
    assert xs == [float(i) for i in range(20)]
