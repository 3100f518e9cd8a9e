"""Faults behind the front: three daphne processes behind a real nginx, one killed (-9)
while a robot and operators are connected through it.

Placement: nginx spreads WebSockets by ``least_conn``, so each long-lived socket opened in
turn lands on a process holding none; the tests check where each landed (the front names the
process in ``UPSTREAM_HEADER``) rather than assume it.
"""

from __future__ import annotations

import asyncio
import contextlib
import io
import itertools
import json
import shutil
import time
from collections.abc import AsyncIterator
from typing import Any

import httpx
import pytest
import websockets
from mcap.reader import make_reader
from mcap_ros1.decoder import DecoderFactory

from cloudnav_web.front import UPSTREAM_HEADER
from robots.agent.client import RosbridgeClient
from telemetry.recording import files
from tests.fixtures_live import BASE_DIR, Front, RosClient, SocketCommunicator, until

pytestmark = [pytest.mark.scaled, pytest.mark.slow]

POSE: dict[str, Any] = {
    "header": {"frame_id": "boccioni_1/Hall"},
    "pose": {"position": {"x": 1, "y": 0.75}},
}
POSE_TYPE = "geometry_msgs/PoseStamped"
GO = {"linear": {"x": 0.3, "y": 0.0, "z": 0.0}, "angular": {"x": 0.0, "y": 0.0, "z": 0.0}}
SEEN_AGAIN = 5.0  # the bound: operators see the robot again within 5 s of the crash
TELEOP_TTL = 5.0  # CLOUDNAV_TELEOP_LOCK_TTL's default
STARTUP = 30.0  # a handshake through the front on a loaded 2-core machine


@pytest.fixture
def front(scaled_servers, nginx_front) -> Front:
    return nginx_front(scaled_servers(3))


@contextlib.asynccontextmanager
async def running(robot: RosbridgeClient) -> AsyncIterator[RosbridgeClient]:
    """Run the robot's client (reconnecting with its own back-off) until the block ends."""
    task = asyncio.create_task(robot.run())
    try:
        async with asyncio.timeout(STARTUP):
            await robot.wait_connected()
        yield robot
    finally:
        await robot.close()
        await asyncio.wait_for(task, STARTUP)


async def operator_through(front: Front, who: str) -> tuple[RosClient, int]:
    """A browser session's rosbridge socket through the front, and the process it reached."""
    socket = await websockets.connect(
        front.server.rosbridge_url(),
        additional_headers={"Cookie": front.cluster.cookies[who], "Origin": front.server.url},
        open_timeout=STARTUP,
    )
    assert socket.response is not None  # set once the handshake succeeded
    return RosClient(SocketCommunicator(socket)), front.process_of(socket.response.headers)


class Page:
    """An operator's open page: the pages' own connection (``static/js/ros.js``, run by
    ``tests/js/page_connection.mjs`` under Node) through the front, subscribed to one topic."""

    def __init__(self, process: asyncio.subprocess.Process) -> None:
        self.process = process

    @classmethod
    @contextlib.asynccontextmanager
    async def open(cls, front: Front, who: str, topic: str, type_name: str) -> AsyncIterator[Page]:
        node = shutil.which("node")
        assert node is not None, "Node 20 is needed: install nodejs"
        args = {
            "url": front.server.rosbridge_url(),
            "cookie": front.cluster.cookies[who],
            "origin": front.server.url,
            "topic": topic,
            "type": type_name,
            "header": UPSTREAM_HEADER,
        }
        script = BASE_DIR / "tests" / "js" / "page_connection.mjs"
        process = await asyncio.create_subprocess_exec(
            node, str(script), json.dumps(args), cwd=BASE_DIR, stdout=asyncio.subprocess.PIPE
        )
        try:
            yield cls(process)
        finally:
            process.kill()
            await process.wait()

    async def next(self, predicate: Any, wait: float) -> dict[str, Any]:
        """Return the first event the page tells that matches ``predicate``, within ``wait``."""
        assert self.process.stdout is not None
        async with asyncio.timeout(wait):
            while line := await self.process.stdout.readline():
                if predicate(event := json.loads(line)):
                    return dict(event)
        raise AssertionError(f"the page ended: exit status {await self.process.wait()}")


async def publish_poses(robot: RosbridgeClient, published: list[int]) -> None:
    """Publish a pose every 0.1 s (a robot's 10 Hz); note the numbers that went out."""
    for seq in itertools.count():
        if await robot.publish("pose", {**POSE, "header": {**POSE["header"], "seq": seq}}):
            published.append(seq)
        await asyncio.sleep(0.1)


async def test_a_robot_whose_process_is_killed_is_seen_again_through_the_front(front):
    robot = RosbridgeClient(front.server.rosbridge_url(), front.cluster.tokens["r1"], seed=1)
    robot.advertise("pose", "geometry_msgs/PoseStamped")
    async with running(robot):
        robots_process = front.process_of(robot.response_headers)
        operator, operators_process = await operator_through(front, "operator")
        assert operators_process != robots_process, "least_conn put both on one process"
        await operator.send(op="subscribe", topic="/r1/pose")
        await operator.sync()
        published: list[int] = []
        publishing = asyncio.create_task(publish_poses(robot, published))
        await operator.receive_until(lambda f: f.get("topic") == "/r1/pose", wait=STARTUP)

        front.cluster.kill(robots_process)
        killed_at, last_before = time.monotonic(), published[-1]
        await until(lambda: robot.connections == 2, "the robot's reconnection", SEEN_AGAIN)
        assert front.process_of(robot.response_headers) != robots_process
        await operator.receive_until(
            lambda f: f.get("topic") == "/r1/pose" and f["msg"]["header"]["seq"] > last_before,
            wait=SEEN_AGAIN - (time.monotonic() - killed_at),
        )  # on the same socket: no reload, no resubscription
        publishing.cancel()
        await operator.close()


async def test_an_operators_page_whose_process_is_killed_resumes_on_another(front):
    robot = RosbridgeClient(front.server.rosbridge_url(), front.cluster.tokens["r1"], seed=4)
    robot.advertise("pose", "geometry_msgs/PoseStamped")
    async with running(robot), Page.open(front, "operator", "/r1/pose", POSE_TYPE) as page:
        reached = (await page.next(lambda e: "connected" in e, STARTUP))["connected"]
        operators_process = front.process_of({UPSTREAM_HEADER: reached})
        assert operators_process != front.process_of(robot.response_headers), "least_conn"
        published: list[int] = []
        publishing = asyncio.create_task(publish_poses(robot, published))
        await page.next(lambda e: "message" in e, STARTUP)

        front.cluster.kill(operators_process)
        killed_at, last_before = time.monotonic(), published[-1]
        reached = (await page.next(lambda e: "connected" in e, SEEN_AGAIN))["connected"]
        assert front.process_of({UPSTREAM_HEADER: reached}) != operators_process
        await page.next(
            lambda e: "message" in e and e["message"]["header"]["seq"] > last_before,
            SEEN_AGAIN - (time.monotonic() - killed_at),
        )
        print(f"the page saw poses again {time.monotonic() - killed_at:.1f} s after the kill")
        publishing.cancel()


async def test_a_recording_the_killed_process_wrote_stays_readable_and_goes_on(
    scaled_servers, nginx_front, tmp_path
):
    root = tmp_path / "recordings"
    front = nginx_front(scaled_servers(3, env={"CLOUDNAV_RECORDING_DIR": str(root)}))
    robot = RosbridgeClient(front.server.rosbridge_url(), front.cluster.tokens["r1"], seed=5)
    robot.advertise("pose", "geometry_msgs/PoseStamped")
    began = time.time()
    async with running(robot):
        robots_process = front.process_of(robot.response_headers)
        # the other processes serve already (their recorders' repair at start is behind them)
        others = [await operator_through(front, who) for who in ("operator", "operator2")]
        assert {process for _, process in others} | {robots_process} == {0, 1, 2}
        published: list[int] = []
        publishing = asyncio.create_task(publish_poses(robot, published))
        await until(lambda: len(published) >= 10, "ten poses published", STARTUP)
        kept = await recorded_poses(front, began)  # flushed: on disk when the process dies
        [left] = files.files_of(root, "r1")

        front.cluster.kill(robots_process)
        killed_at = time.monotonic()
        await until(lambda: robot.connections == 2, "the robot's reconnection", SEEN_AGAIN)
        await until(lambda: files.finished(left.path), "the dead process's file repaired", 20)
        repaired_after = time.monotonic() - killed_at
        assert set(kept) <= set(indexed_poses(left.path))  # nothing flushed is lost
        resumed = published[-1]
        await until(lambda: published[-1] >= resumed + 10, "ten more poses", STARTUP)
        assert max(await recorded_poses(front, began)) > resumed  # by its new process
        assert len(files.files_of(root, "r1")) == 2
        publishing.cancel()
        for operator, _ in others:
            await operator.close()
    print(f"the dead process's file was repaired {repaired_after:.1f} s after the kill")


async def recorded_poses(front: Front, began: float) -> list[int]:
    """The sequence numbers of r1's recorded poses since ``began``, as an operator exports
    them through the front (the robot's process writes out what it holds first)."""
    url = f"{front.server.url}/api/robots/r1/recording.mcap?start={began - 5}&end={time.time() + 5}"
    async with httpx.AsyncClient(timeout=STARTUP) as http:
        response = await http.get(url, headers={"Cookie": front.cluster.cookies["operator"]})
    assert response.status_code == 200
    reader = make_reader(io.BytesIO(response.content), decoder_factories=[DecoderFactory()])
    return [
        ros.header.seq
        for _s, channel, _m, ros in reader.iter_decoded_messages()
        if channel.topic == "/r1/pose"
    ]


def indexed_poses(path: Any) -> list[int]:
    """The sequence numbers of the poses in a finished file, read by its summary's index."""
    with open(path, "rb") as stream:
        reader = make_reader(stream, decoder_factories=[DecoderFactory()])
        assert reader.get_summary() is not None  # a footer and an index, as written whole
        return [
            ros.header.seq for _s, _c, _m, ros in reader.iter_decoded_messages(topics=["/r1/pose"])
        ]


async def test_a_teleop_lock_held_through_a_killed_process_lapses_and_nothing_drives(front):
    commands: list[tuple[float, Any]] = []
    robot = RosbridgeClient(front.server.rosbridge_url(), front.cluster.tokens["r1"], seed=2)
    robot.subscribe(
        "cmd_vel", "geometry_msgs/Twist", lambda m: commands.append((time.monotonic(), m))
    )
    async with running(robot):
        await robot.call_service("/rosapi/get_time")  # its subscription is in place
        holder, holders_process = await operator_through(front, "operator")
        other, others_process = await operator_through(front, "operator2")
        robots_process = front.process_of(robot.response_headers)
        assert len({robots_process, holders_process, others_process}) == 3, "least_conn"
        lock = {"robot": "r1", "action": "acquire"}
        assert (await holder.call("/cloudnav/teleop_lock", lock))["values"]["success"] is True
        driving = asyncio.create_task(drive(holder))
        await until(lambda: any(m == GO for _, m in commands), "the holder's command")

        front.cluster.kill(holders_process)
        killed_at = time.monotonic()
        driving.cancel()
        await until(
            lambda: any(at > killed_at and not moving(m) for at, m in commands),
            "a stop from the robot's process",
            TELEOP_TTL,
        )
        stopped_after = time.monotonic() - killed_at
        refused = (await other.call("/cloudnav/teleop_lock", lock))["values"]
        assert refused["holder"] == "user:operator"  # held through the dead process
        while not (await other.call("/cloudnav/teleop_lock", lock))["values"]["success"]:
            assert time.monotonic() - killed_at < TELEOP_TTL + 5.0, "the lock never lapsed"
            await asyncio.sleep(0.2)
        await other.call("/cloudnav/teleop_lock", {"robot": "r1", "action": "release"})
        await robot.call_service("/rosapi/get_time")  # anything sent to it has arrived
        assert [m for at, m in commands if at > killed_at and moving(m)] == []
        await other.close()
    print(f"the robot was stopped {stopped_after:.1f} s after the holder's process died")


async def drive(holder: RosClient) -> None:
    """Send the robot forward at 10 Hz, as a held joystick does."""
    while True:
        with contextlib.suppress(websockets.ConnectionClosed):
            await holder.send(op="publish", topic="/r1/cmd_vel", msg=GO)
        await asyncio.sleep(0.1)


def moving(twist: Any) -> bool:
    return any(value for part in twist.values() for value in part.values())


REDIS_DOWN = 10.0  # the outage: Redis killed, empty when it comes back (as a restart)
REDIS_BACK = 15.0  # poses, listings and latched messages again after Redis is back (loaded)


@pytest.fixture
def redis_front(scaled_servers, nginx_front, private_redis) -> Front:
    """Two processes behind the front, on a Redis of the test's own (to stop and start)."""
    return nginx_front(scaled_servers(2, env={"REDIS_URL": private_redis.url}))


async def test_a_restarted_redis_recovers_without_restarting_any_process(
    redis_front, private_redis
):
    front = redis_front
    commands: list[tuple[float, Any]] = []
    robot = RosbridgeClient(front.server.rosbridge_url(), front.cluster.tokens["r1"], seed=3)
    robot.advertise("pose", "geometry_msgs/PoseStamped")
    robot.advertise("map_id", "std_msgs/String", latch=True)
    robot.subscribe(
        "cmd_vel", "geometry_msgs/Twist", lambda m: commands.append((time.monotonic(), m))
    )
    async with running(robot):
        await robot.publish("map_id", {"data": "boccioni_1/Hall"})
        operator, operators_process = await operator_through(front, "operator")
        assert operators_process != front.process_of(robot.response_headers), "least_conn"
        await operator.send(op="subscribe", topic="/r1/pose")
        published: list[int] = []
        publishing = asyncio.create_task(publish_poses(robot, published))
        await operator.receive_until(lambda f: f.get("topic") == "/r1/pose", wait=STARTUP)
        lock = {"robot": "r1", "action": "acquire"}
        assert (await operator.call("/cloudnav/teleop_lock", lock))["values"]["success"] is True
        # The holder drives through the outage, so its lock must outlive Redis's restart.
        driving = asyncio.create_task(drive(operator))
        await until(lambda: any(m == GO for _, m in commands), "the holder's command")
        logged = [server.log_lines() for server in front.cluster.servers]

        private_redis.stop()
        await asyncio.sleep(REDIS_DOWN)  # the outage itself is what is tested
        await asyncio.to_thread(private_redis.start)
        back_at, last_before = time.monotonic(), published[-1]

        await operator.receive_until(
            lambda f: f.get("topic") == "/r1/pose" and f["msg"]["header"]["seq"] > last_before,
            wait=REDIS_BACK,
        )  # on the same socket, subscribed before the outage
        poses_after = time.monotonic() - back_at
        await until(lambda: topics_listed(operator), "/r1/pose listed by rosapi", REDIS_BACK)
        listed_after = time.monotonic() - back_at
        await operator.send(op="subscribe", topic="/r1/map_id", id="late")
        latched = await operator.receive_until(lambda f: f.get("topic") == "/r1/map_id")
        assert latched["msg"] == {"data": "boccioni_1/Hall"}
        await lock_kept_by_its_driving_holder(front, commands, back_at)
        driving.cancel()
        publishing.cancel()
        await operator.close()
    for server, since in zip(front.cluster.servers, logged, strict=True):
        told = [
            line for line in server.told_since(since) if " WARNING " in line or " ERROR " in line
        ]
        # the outage said once and then every 10 s, not once per loop per attempt
        assert len(told) <= 8, "\n".join(told)
        assert not any(line.startswith("Traceback") for line in server.told_since(since))
        assert server.process.poll() is None  # none restarted
    print(f"Redis back: poses after {poses_after:.1f} s, listed after {listed_after:.1f} s")


async def topics_listed(operator: RosClient) -> bool:
    listed = await operator.call("/rosapi/topics", id="topics")
    return bool(listed["result"]) and "/r1/pose" in listed["values"]["topics"]


async def lock_kept_by_its_driving_holder(
    front: Front, commands: list[tuple[float, Any]], back_at: float
) -> None:
    """After the outage the operator, who drove through it, holds r1's lock again (its
    process wrote the lock back into the empty Redis at its next renewal), its commands
    reach the robot again and another operator is refused it."""
    other, _ = await operator_through(front, "operator2")
    status = {"robot": "r1", "action": "status"}

    async def held_again() -> bool:
        answer = await other.call("/cloudnav/teleop_lock", status)
        return bool(answer["values"]["holder"] == "user:operator")

    await until(held_again, "the holder's lock written back into Redis", TELEOP_TTL)
    await until(
        lambda: any(at > back_at and m == GO for at, m in commands),
        "the holder's commands after the outage",
        REDIS_BACK,
    )
    ask = {"robot": "r1", "action": "acquire"}
    refused = (await other.call("/cloudnav/teleop_lock", ask))["values"]
    assert refused["success"] is False
    assert refused["holder"] == "user:operator"
    await other.close()
