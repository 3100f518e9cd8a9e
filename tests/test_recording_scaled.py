"""Scaled mode: a robot is recorded once, by the process it is connected to, even when
its topics also reach the other process (a viewer there subscribes to them)."""

from __future__ import annotations

import asyncio
import json
import time

import pytest
import websockets

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
