"""The end-to-end operator: a browser-like rosbridge session that watches and commands the
robot, and how far a pose is from a goal."""

from __future__ import annotations

import asyncio
import contextlib
import json
import math
import time
from pathlib import Path
from typing import Any

from tests.support.logs import tail

ROBOT = "robot_0"
BUILDING = "boccioni_1"
LEG_DEADLINE = 300.0  # wall seconds for either trip; about a minute each, more when busy
SUCCEEDED, TERMINAL_FAILURES = 3, {2, 4, 5, 8, 9}


class Operator:
    """An operator's browser-like rosbridge session watching and commanding the robot."""

    def __init__(self, ws: Any) -> None:
        self.ws = ws
        self.pose: dict[str, Any] | None = None
        self.statuses: dict[str, tuple[int, str]] = {}
        self.heard = False  # any nav_status yet

    async def send(self, **frame: Any) -> None:
        await self.ws.send(json.dumps(frame))

    async def watch(self) -> None:
        for topic in ("pose", "nav_status"):
            await self.send(op="subscribe", topic=f"/{ROBOT}/{topic}")

    async def pump(self, wait: float) -> None:
        """Read frames for up to ``wait`` seconds, keeping the latest pose and statuses."""
        with contextlib.suppress(TimeoutError):
            frame = json.loads(await asyncio.wait_for(self.ws.recv(), wait))
            if frame.get("topic") == f"/{ROBOT}/pose":
                self.pose = frame["msg"]
            elif frame.get("topic") == f"/{ROBOT}/nav_status":
                self.heard = True
                for entry in frame["msg"]["status_list"]:
                    self.statuses[entry["goal_id"]["id"]] = (entry["status"], entry["text"])

    async def send_goal(self, map_code: str, pose: tuple[float, float, float]) -> None:
        x, y, yaw = pose
        msg = {
            "header": {"frame_id": f"{BUILDING}/{map_code}"},
            "pose": {
                "position": {"x": x, "y": y, "z": 0.0},
                "orientation": {"x": 0.0, "y": 0.0, "z": math.sin(yaw / 2), "w": math.cos(yaw / 2)},
            },
        }
        await self.send(op="publish", topic=f"/{ROBOT}/goal", msg=msg)

    async def until_succeeded(self, goal_id: str, agent_log: Path) -> None:
        give_up = time.monotonic() + LEG_DEADLINE
        while self.statuses.get(goal_id, (None,))[0] != SUCCEEDED:
            status = self.statuses.get(goal_id)
            assert status is None or status[0] not in TERMINAL_FAILURES, (status, tail(agent_log))
            assert time.monotonic() < give_up, (status, tail(agent_log))
            await self.pump(1.0)

    async def until_listening(self, agent_log: Path) -> None:
        """Until the robot's first ``nav_status``: it subscribed to its goal before it
        published anything, so a goal sent now reaches it."""
        give_up = time.monotonic() + 30
        while not self.heard:
            assert time.monotonic() < give_up, tail(agent_log)
            await self.pump(1.0)


def position_error(pose: dict[str, Any], goal: tuple[float, float, float]) -> float:
    position = pose["pose"]["position"]
    return math.hypot(position["x"] - goal[0], position["y"] - goal[1])
