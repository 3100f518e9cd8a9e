"""The demo's robots with their tokens (the ``tokens`` fixture, a pytest plugin of
tests/conftest.py) and an operator's rosbridge session that keeps the newest message of
each topic, as the fleet and whereabouts tests use them."""

from __future__ import annotations

import asyncio
import contextlib
import io
import json
import math
import time
from pathlib import Path
from typing import Any

import pytest
from django.core.management import call_command

from tests.support.logs import tail

DEMO_ROBOTS = 3  # scripts/demo.sh's default ROBOTS
LOCALISED_WITHIN = 45.0  # wall seconds from the agent's start, for every demo robot


@pytest.fixture
def tokens(tmp_path: Path) -> Path:
    path = tmp_path / "tokens.json"
    call_command(
        "seed_demo", "--robots", str(DEMO_ROBOTS), "--tokens-file", str(path), stdout=io.StringIO()
    )
    return path


class Operator:
    """An operator's rosbridge session keeping the newest message of each topic."""

    def __init__(self, ws: Any) -> None:
        self.ws = ws
        self.latest: dict[str, dict[str, Any]] = {}
        self.heard: dict[str, list[dict[str, Any]]] = {}
        self.statuses: list[dict[str, Any]] = []  # the server's ``status`` frames

    async def subscribe(self, *topics: str) -> None:
        for topic in topics:
            await self.ws.send(json.dumps({"op": "subscribe", "topic": topic}))

    async def publish(self, topic: str, msg: dict[str, Any]) -> None:
        await self.ws.send(json.dumps({"op": "publish", "topic": topic, "msg": msg}))

    async def until(self, done: Any, deadline: float, log: Path) -> None:
        """Read frames until ``done()``; fail with the agent's log after ``deadline`` s."""
        give_up = time.monotonic() + deadline
        while not done():
            assert time.monotonic() < give_up, tail(log)
            with contextlib.suppress(TimeoutError):
                frame = json.loads(await asyncio.wait_for(self.ws.recv(), 1.0))
                if frame.get("op") == "publish":
                    self.latest[frame["topic"]] = frame["msg"]
                    self.heard.setdefault(frame["topic"], []).append(frame["msg"])
                elif frame.get("op") == "status":
                    self.statuses.append(frame)


def state_of(status: dict[str, Any] | None) -> dict[str, str]:
    """The ``values`` of a ``DiagnosticStatus`` as a dict."""
    return {v["key"]: v["value"] for v in (status or {}).get("values", [])}


def pose(map_id: str, x: float, y: float, yaw: float) -> dict[str, Any]:
    return {
        "header": {"frame_id": map_id},
        "pose": {
            "position": {"x": x, "y": y, "z": 0.0},
            "orientation": {"x": 0.0, "y": 0.0, "z": math.sin(yaw / 2), "w": math.cos(yaw / 2)},
        },
    }
