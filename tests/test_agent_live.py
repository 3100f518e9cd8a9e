"""A robot on the network, as an operator's browser session meets it through a real daphne:
initial pose, goal and cancel (``/robot_0/cancel_goal``), teleop under the server's lock."""

from __future__ import annotations

import asyncio
import contextlib
import json
import math
import time
from collections.abc import AsyncIterator, Callable
from typing import Any

import pytest
import websockets

from cloudnav_core.params import RobotConfig
from robots.agent.fleet import FleetOptions, FleetRobot, build_robot, run_fleet
from robots.agent.sim.world import demo_world
from tests.fixtures_live import LiveServer

pytestmark = pytest.mark.django_db(transaction=True)

ROBOT = "robot_0"
CORRIDOR_A = "boccioni_1/CorridorA"
START = (8.0, 23.2, 0.0)
PREEMPTED, ACTIVE = 2, 1


@pytest.fixture
async def online(
    daphne_server: LiveServer, demo_token: str
) -> AsyncIterator[Callable[[float], FleetRobot]]:
    """``online(time_scale)``: the robot running in this process, connected to daphne."""
    running: list[asyncio.Task[None]] = []

    def start(time_scale: float) -> FleetRobot:
        options = FleetOptions(daphne_server.url, start=START, particles=200, robot=RobotConfig())
        member = build_robot(ROBOT, demo_token, demo_world(daphne_server.url), options)
        running.append(asyncio.create_task(run_fleet([member], time_scale)))
        return member

    yield start
    for task in running:
        task.cancel()
        with contextlib.suppress(asyncio.CancelledError):
            await task


class Operator:
    """An operator's rosbridge session: frames are read into ``latest`` by topic and
    ``answers`` by call id."""

    def __init__(self, ws: Any) -> None:
        self.ws = ws
        self.latest: dict[str, dict[str, Any]] = {}
        self.answers: dict[str, dict[str, Any]] = {}

    async def send(self, **frame: Any) -> None:
        await self.ws.send(json.dumps(frame))

    async def until(self, done: Callable[[], bool], what: str, deadline: float = 20.0) -> None:
        give_up = time.monotonic() + deadline
        while not done():
            assert time.monotonic() < give_up, f"timed out waiting for {what}: {self.latest}"
            with contextlib.suppress(TimeoutError):
                self._note(json.loads(await asyncio.wait_for(self.ws.recv(), 0.5)))

    async def read_for(self, seconds: float) -> None:
        """Take in whatever arrives for ``seconds``."""
        give_up = time.monotonic() + seconds
        while (left := give_up - time.monotonic()) > 0:
            with contextlib.suppress(TimeoutError):
                self._note(json.loads(await asyncio.wait_for(self.ws.recv(), left)))

    def _note(self, frame: dict[str, Any]) -> None:
        if frame.get("op") == "publish":
            self.latest[frame["topic"]] = frame["msg"]
        elif frame.get("op") == "service_response":
            self.answers[frame.get("id", "")] = frame

    async def call(self, service: str, args: dict[str, Any], call_id: str) -> dict[str, Any]:
        await self.send(op="call_service", id=call_id, service=service, args=args)
        await self.until(lambda: call_id in self.answers, f"the answer to {service}")
        return self.answers[call_id]

    def last_status(self) -> int | None:
        status = self.latest.get(f"/{ROBOT}/nav_status", {}).get("status_list", [])
        return status[-1]["status"] if status else None

    def speed(self) -> float:
        odom = self.latest.get(f"/{ROBOT}/odom")
        return float(odom["twist"]["twist"]["linear"]["x"]) if odom else 0.0

    async def send_goal(self, goal: dict[str, Any]) -> None:
        await self.send(op="publish", topic=f"/{ROBOT}/goal", msg=goal)

    def distance_to(self, point: tuple[float, ...]) -> float:
        """Metres from the robot's latest ``pose`` to ``point`` (x, y, ...)."""
        here = self.latest[f"/{ROBOT}/pose"]["pose"]["position"]
        return math.dist((here["x"], here["y"]), point[:2])

    async def watch(self, *topics: str) -> None:
        """Subscribe to the robot's ``topics``."""
        for topic in topics:
            await self.send(op="subscribe", topic=f"/{ROBOT}/{topic}")

    def entered(self, map_id: str) -> bool:
        """Whether the robot's latest ``map_id`` is ``map_id`` (of any version)."""
        held = self.latest.get(f"/{ROBOT}/map_id", {}).get("data", "")
        return bool(held.split("@")[0] == map_id)

    def status_text(self) -> str:
        status = self.latest.get(f"/{ROBOT}/nav_status", {}).get("status_list", [])
        return str(status[-1]["text"]) if status else ""

    async def cancel_goal(self) -> None:
        """Cancel the robot's goal, and wait until it says PREEMPTED."""
        answer = await self.call(f"/{ROBOT}/cancel_goal", {}, "cancel")
        assert answer["result"] is True
        await self.until(lambda: self.last_status() == PREEMPTED, "PREEMPTED", 30)

    async def teleop_until(self, reached: Callable[[], object], angular: float) -> None:
        """Take the robot's teleop lock and turn it at ``angular`` until ``reached()``
        (30 s at most)."""
        lock = await self.call("/cloudnav/teleop_lock", {"robot": ROBOT}, "lock")
        assert lock["values"]["success"] is True
        turn = {"linear": {"x": 0.0, "y": 0, "z": 0}, "angular": {"x": 0, "y": 0, "z": angular}}
        give_up = time.monotonic() + 30
        while not reached():
            assert time.monotonic() < give_up, "teleop never reached cmd_vel"
            await self.send(op="publish", topic=f"/{ROBOT}/cmd_vel", msg=turn)
            await self.read_for(0.1)


def pose(map_id: str, x: float, y: float, yaw: float) -> dict[str, Any]:
    return {
        "header": {"frame_id": map_id},
        "pose": {
            "position": {"x": x, "y": y, "z": 0.0},
            "orientation": {"x": 0.0, "y": 0.0, "z": math.sin(yaw / 2), "w": math.cos(yaw / 2)},
        },
    }


def with_covariance(msg: dict[str, Any]) -> dict[str, Any]:
    covariance = [0.0] * 36
    covariance[0] = covariance[7] = covariance[35] = 0.02**2
    return {"header": msg["header"], "pose": {"pose": msg["pose"], "covariance": covariance}}


async def test_an_operator_places_the_robot_sends_a_goal_and_cancels_it(
    daphne_server, operator_headers, online
):
    online(4.0)
    url = daphne_server.rosbridge_url()
    async with websockets.connect(url, additional_headers=operator_headers) as ws:
        operator = Operator(ws)
        for topic in ("pose", "nav_status", "map_id"):
            await operator.send(op="subscribe", topic=f"/{ROBOT}/{topic}")
        await operator.until(lambda: f"/{ROBOT}/nav_status" in operator.latest, "the robot")

        placed = with_covariance(pose(CORRIDOR_A, *START))
        await operator.send(op="publish", topic=f"/{ROBOT}/initialpose", msg=placed)
        await operator.until(lambda: f"/{ROBOT}/pose" in operator.latest, "a pose in a map")
        assert operator.latest[f"/{ROBOT}/map_id"] == {"data": f"{CORRIDOR_A}@v1"}
        assert operator.latest[f"/{ROBOT}/pose"]["header"]["frame_id"] == CORRIDOR_A

        await operator.send(op="publish", topic=f"/{ROBOT}/goal", msg=pose(CORRIDOR_A, 16, 23.2, 0))
        await operator.until(lambda: operator.last_status() == ACTIVE, "the goal taken")
        answer = await operator.call(f"/{ROBOT}/cancel_goal", {}, "cancel")
        assert answer["result"] is True
        assert answer["values"] == {"success": True, "message": "cancelled"}
        await operator.until(lambda: operator.last_status() == PREEMPTED, "PREEMPTED")


async def test_the_lock_holder_drives_it_and_it_stops_when_the_commands_stop(
    daphne_server, operator_headers, online
):
    online(1.0)  # real time: the operator's commands come at wall-clock pace
    url = daphne_server.rosbridge_url()
    async with websockets.connect(url, additional_headers=operator_headers) as ws:
        operator = Operator(ws)
        await operator.send(op="subscribe", topic=f"/{ROBOT}/odom")
        await operator.until(lambda: f"/{ROBOT}/odom" in operator.latest, "the robot")
        lock = await operator.call("/cloudnav/teleop_lock", {"robot": ROBOT}, "lock")
        assert lock["values"]["success"] is True
        go = {"linear": {"x": 0.9, "y": 0, "z": 0}, "angular": {"x": 0, "y": 0, "z": 0}}
        give_up = time.monotonic() + 10
        while operator.speed() < 0.45:  # beyond its limit: clamped to 0.5 m/s
            assert time.monotonic() < give_up, "it never drove"
            await operator.send(op="publish", topic=f"/{ROBOT}/cmd_vel", msg=go)
            await operator.read_for(0.1)
        assert operator.speed() <= 0.5 + 1e-6
        await operator.until(lambda: operator.speed() == 0.0, "a stop", deadline=5)
