"""A flood of relocalisation requests by people never holds up a robot's own, and is
refused in part rather than queued without end (issue 23 point 13).

Over real sockets against daphne. Operators ask ``/cloudnav/relocalise`` back to back,
each with eight images (decoding and features: about eight times a robot's one-image
call); meanwhile the robot asks with one image. Were the calls served in arrival order
(they were: three viewers' sockets delayed a robot's call by 8.8 s), the robot's call
would wait for the operators' calls ahead of it; served first, on the share of the
threads people never take, it waits for nothing. No keyframes are stored, so every call
costs its decoding and features alone. Over REST, people asking at once beyond the
lanes' room are answered 503 with Retry-After at once.
"""

from __future__ import annotations

import asyncio
import base64
import json
import threading
import time
import urllib.error
import urllib.request
from pathlib import Path
from typing import Any

import pytest
import websockets
from channels.db import database_sync_to_async

from cloudnav_core.messages import CompressedImage, compressed_image
from maps.models import Building
from robots.agent.hardware import encode_jpeg
from robots.agent.sim.camera import Camera
from robots.agent.sim.world import demo_world
from tests.conftest import make_user
from tests.fixtures_live import LiveServer, LiveServers, session_cookie

OPERATORS = 3
ROBOT_CALLS = 5
DEADLINE = 120.0
BUSY = "the server is answering other relocalisation requests; ask again shortly"


@pytest.fixture
def server(daphne_servers: LiveServers, demo_token: str, tmp_path: Path) -> LiveServer:
    return daphne_servers.start(
        env={"CLOUDNAV_KEYFRAME_DIR": str(tmp_path / "keyframes"), "CLOUDNAV_RELOCALISE_QUEUE": "2"}
    )


def views(count: int) -> list[CompressedImage]:
    """``count`` views of Corridor A, turning on the spot, as robots send them."""
    camera = Camera(demo_world(seed=0))
    return [
        compressed_image("camera", encode_jpeg(camera.render((6.0, 23.2, 0.8 * n))), 1.0)
        for n in range(count)
    ]


def operators(count: int) -> list[dict[str, str]]:
    """Handshake headers of ``count`` operators of the demo building (sessions)."""
    building = Building.objects.get(code="boccioni_1")
    headers = []
    for n in range(count):
        person = make_user(f"asker{n}", "operator")
        building.members.add(person)
        headers.append({"Cookie": session_cookie(person).decode()})
    return headers


async def ask(socket: Any, images: list[CompressedImage], ident: str) -> dict[str, Any]:
    call = {"op": "call_service", "id": ident, "service": "/cloudnav/relocalise"}
    await socket.send(json.dumps({**call, "args": {"images": images}}))
    async with asyncio.timeout(DEADLINE):
        while (reply := json.loads(await socket.recv())).get("id") != ident:
            pass
    return dict(reply)


class Asking:
    """Operators asking back to back until stopped: when each of their answers came."""

    def __init__(self) -> None:
        self.answered: list[float] = []
        self.stopped = asyncio.Event()

    async def ask_until_stopped(self, socket: Any, images: list[CompressedImage]) -> None:
        while not self.stopped.is_set():
            reply = await ask(socket, images, "operator")
            if reply["result"] is False and reply["values"] == BUSY:
                # An operator asking again the instant its answer came can find the other
                # two still waiting before a thread takes the next: the lane is full for
                # that instant, and the answer says to ask again shortly.
                await asyncio.sleep(0.05)
                continue
            assert reply["result"] is True, reply
            self.answered.append(time.monotonic())

    def between(self, start: float, end: float) -> int:
        return sum(start < t < end for t in self.answered)


async def test_a_robots_call_is_not_held_up_by_operators_asking_back_to_back(
    server: LiveServer, demo_token: str
) -> None:
    """Three operators keep one call each going: one runs, two wait. In arrival order
    the robot's call waited for the running calls to end and the waiting ones to start
    (two or more operators' answers while it waited, each time); served first, on the
    thread people never take, at most the one call running ends meanwhile."""
    headers = await database_sync_to_async(operators)(OPERATORS)
    eight, one = views(8), views(1)
    asking = Asking()
    async with websockets.connect(server.rosbridge_url(demo_token)) as robot:
        people = [
            await websockets.connect(
                server.rosbridge_url(), additional_headers={**h, "Origin": server.url}
            )
            for h in headers
        ]
        tasks = [asyncio.create_task(asking.ask_until_stopped(s, eight)) for s in people]
        try:
            give_up = time.monotonic() + DEADLINE
            while len(asking.answered) < OPERATORS:  # the operators' calls are going
                assert time.monotonic() < give_up, "the operators' calls were not answered"
                await asyncio.sleep(0.05)
            overtaken = []
            for n in range(ROBOT_CALLS):
                started = time.monotonic()
                reply = await ask(robot, one, f"robot{n}")
                overtaken.append(asking.between(started, time.monotonic()))
                assert reply["result"] is True, reply
                assert reply["values"]["reason"] == "no keyframes are stored for this building yet"
        finally:
            asking.stopped.set()
            await asyncio.gather(*tasks)
            for socket in people:
                await socket.close()
    assert sum(overtaken) <= ROBOT_CALLS, overtaken


def post(server: LiveServer, body: bytes, person: str) -> tuple[int, str | None]:
    """POST ``body`` to ``/api/relocalise`` as ``person`` (make_user's password)."""
    credentials = base64.b64encode(f"{person}:pw-{person}".encode()).decode()
    request = urllib.request.Request(
        server.url + "/api/relocalise",
        data=body,
        headers={"Authorization": f"Basic {credentials}", "Content-Type": "application/json"},
    )
    try:
        with urllib.request.urlopen(request, timeout=DEADLINE) as response:
            return response.status, None
    except urllib.error.HTTPError as refused:
        return refused.code, refused.headers.get("Retry-After")


async def test_people_asking_at_once_over_rest_beyond_the_lanes_room_are_refused(
    server: LiveServer, demo_token: str
) -> None:
    """One call runs on the people's share, two wait (``CLOUDNAV_RELOCALISE_QUEUE``); the
    other three of six asking at once are answered 503 at once. Unbounded, all six ran
    at once on threads of their own, and every other request of the server waited."""
    await database_sync_to_async(operators)(6)
    body = json.dumps({"images": views(8)}).encode()
    start = threading.Barrier(6)

    def one(person: str) -> tuple[int, str | None]:
        start.wait(DEADLINE)
        return post(server, body, person)

    answers = await asyncio.gather(*(asyncio.to_thread(one, f"asker{n}") for n in range(6)))
    statuses = sorted(code for code, _ in answers)
    assert set(statuses) == {200, 503}, statuses
    assert statuses.count(200) >= 3
    assert {wait for code, wait in answers if code == 503} == {"1"}
