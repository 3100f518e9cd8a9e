"""An operator of the live agent tests: a rosbridge session that reads frames by topic and
sends goals, the demo robot's names and start, and the messages it sends."""

from __future__ import annotations

import asyncio
import contextlib
import json
import math
import time
from collections.abc import Callable
from typing import Any

ROBOT = "robot_0"
CORRIDOR_A = "boccioni_1/CorridorA"
START = (8.0, 23.2, 0.0)
PREEMPTED, ACTIVE = 2, 1


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
