"""A bounded fuzzer over every rosbridge op and field, in JSON and in CBOR, against a live
server: after each frame the connection must still answer, and the server's memory must
stay within a bound.

Frames come from a seeded generator (``FUZZ_SEED`` in the environment replays a run), a
fixed number per format and never more than ``TIME_BUDGET`` seconds in all, so the test
stays a few seconds long in ``make test``.
"""

from __future__ import annotations

import json
import math
import os
import random
import time
from typing import Any

import cbor2
import pytest

from tests.hostile import LiveRosbridge, cbor_frame, cbor_tag, server_memory, shared_reference_bomb

FRAMES_PER_FORMAT = 150
TIME_BUDGET = 20.0
MEMORY_BOUND = 128 * 2**20
SEED = int(os.environ.get("FUZZ_SEED", "20261124"))

# Every op with its fields, as ``telemetry.domain.protocol`` parses them.
FIELDS: dict[str, list[str]] = {
    "advertise": ["topic", "type", "id", "latch"],
    "unadvertise": ["topic", "id"],
    "publish": ["topic", "msg", "id", "latch"],
    "subscribe": [
        "topic",
        "id",
        "type",
        "throttle_rate",
        "queue_length",
        "fragment_size",
        "compression",
    ],
    "unsubscribe": ["topic", "id"],
    "call_service": ["service", "id", "args", "type", "fragment_size", "compression"],
    "service_response": ["service", "result", "id", "values"],
    "advertise_service": ["service", "type"],
    "unadvertise_service": ["service"],
    "advertise_action": ["action", "type"],
    "unadvertise_action": ["action"],
    "send_action_goal": [
        "action",
        "action_type",
        "id",
        "args",
        "feedback",
        "fragment_size",
        "compression",
    ],
    "cancel_action_goal": ["action", "id"],
    "action_feedback": ["action", "id", "values"],
    "action_result": ["action", "status", "result", "id", "values"],
    "fragment": ["id", "data", "num", "total"],
    "set_level": ["level", "id"],
}

NAMES = [
    "pose",
    "odom",
    "/r1/scan",
    "/r2/pose",
    "/rosapi/topics",
    "/rosapi/set_param",
    "/rosapi/get_param",
    "/cloudnav/route",
    "rosapi/get_time",
    "map_id",
    "cmd_vel",
    "/fleet/x",
    "~private",
    "bad name",
    "/a//b",
    "/" + "n" * 300,
    "",
]
TYPES = ["std_msgs/String", "geometry_msgs/msg/PoseStamped", "nav_msgs/Odometry", "x/Y", ""]


class Generator:
    """Frames of every op, each field a valid value, a wrong one, or something absurd."""

    def __init__(self, rng: random.Random, binary: bool) -> None:
        self.rng = rng
        self.binary = binary

    def frame(self) -> str | bytes:
        if self.rng.random() < 0.08:
            return self.raw()
        op = self.rng.choice([*FIELDS, "teleport", None])
        frame: dict[str, Any] = {} if op is None else {"op": op}
        for name in FIELDS.get(op or "", []):
            if self.rng.random() < 0.93:
                frame[name] = self.value(name)
        if self.rng.random() < 0.1:
            frame[self.text()] = self.anything(3)
        return cbor2.dumps(frame) if self.binary else json.dumps(frame)

    def value(self, field: str) -> Any:
        if self.rng.random() < 0.1:
            return self.anything(4)
        rng = self.rng
        if field in ("topic", "service", "action"):
            return rng.choice(NAMES)
        if field in ("type", "action_type"):
            return rng.choice(TYPES)
        if field in ("msg", "args", "values"):
            return self.message()
        if field == "compression":
            return rng.choice(["none", "cbor", "png", "cbor-raw", "zip"])
        if field == "level":
            return rng.choice(["info", "warning", "error", "none", "loud"])
        if field == "data":
            return rng.choice(['{"op": "get_time"', "x" * rng.randint(0, 70_000), ""])
        if field in ("num", "total", "status", "throttle_rate", "queue_length", "fragment_size"):
            return rng.choice([0, 1, 2, 3, -1, 100, 2**31, 2**63 - 1, 1.5, 10.0])
        if field in ("latch", "result", "feedback"):
            return rng.choice([True, False, 0, "yes"])
        return rng.choice(["f1", "call", 7, -3, 2**63, "x" * 2000, ""])  # id

    def message(self) -> Any:
        rng = self.rng
        choice = rng.randrange(6)
        if choice == 0:
            return {"data": self.text()}
        if choice == 1:
            return {"data": [rng.random() for _ in range(rng.randint(0, 20_000))]}
        if choice == 2:
            return {"header": {"stamp": {"sec": 1, "nanosec": 2}, "frame_id": self.text()}}
        if choice == 3:
            return self.nested(rng.randint(10, 900))  # deeper ones come as raw text
        if choice == 4:
            return {"name": rng.choice(NAMES), "value": rng.choice(["1", "[1,", '"x"', "nan"])}
        return {"x": rng.choice([math.nan, math.inf, -0.0, 1e308, -(2**63)])}

    def nested(self, depth: int) -> Any:
        value: Any = "leaf"
        for _ in range(depth):
            value = [value] if self.rng.random() < 0.5 else {"k": value}
        return value

    def anything(self, depth: int) -> Any:
        rng = self.rng
        pick = rng.randrange(9 if depth else 6)
        if pick == 0:
            return None
        if pick == 1:
            return rng.choice([True, False])
        if pick == 2:
            return rng.choice([0, -1, 2**64 - 1, 2**70, 1e300, -1e-300, 0.5])
        if pick == 3:
            return self.text()
        if pick == 4:
            return b"\x00\xff" * rng.randint(0, 100) if self.binary else "AP8="
        if pick == 5:
            return math.nan if not self.binary else math.inf
        if pick == 6:
            return [self.anything(depth - 1) for _ in range(rng.randint(0, 5))]
        if pick == 7:
            return {self.text(): self.anything(depth - 1) for _ in range(rng.randint(0, 5))}
        return self.nested(rng.randint(1, 200))

    def text(self) -> str:
        # A lone surrogate is JSON's only: JSON escapes it, CBOR has no way to write it.
        odd = "\x00" if self.binary else "\ud800"
        return self.rng.choice(["", "a", "\u00e9\u20ac\U0001f600", odd, "x" * 5000, "%s{}[]\\"])

    def raw(self) -> str | bytes:
        """A frame no encoder writes: truncated, tagged, shared, or not a frame at all."""
        rng = self.rng
        if not self.binary:
            return rng.choice(["", "{", "42", "null", '{"op":', "[" * 5000, '{"op":"x"}' * 3])
        options = [
            b"",
            b"\xa1",
            rng.randbytes(rng.randint(1, 64)),
            cbor_frame(
                {"op": "publish", "topic": "odom"}, msg=cbor_tag(rng.randrange(300), b"\x00")
            ),
            cbor_frame(
                {"op": "call_service", "service": "/x", "args": 1},
                id=shared_reference_bomb(rng.randint(8, 64)),
            ),
            b"\x81" * 10_000 + b"\x00",
        ]
        return rng.choice(options)


@pytest.mark.parametrize("binary", [False, True], ids=["json", "cbor"])
async def test_every_op_and_field_fuzzed_leaves_the_connection_answering(
    daphne_server, token, binary
):
    rng = random.Random(f"{SEED}-{binary}")
    generate = Generator(rng, binary)
    client = await LiveRosbridge.connect(daphne_server, token)
    await client.send({"op": "set_level", "level": "info"})
    base = server_memory(daphne_server)
    give_up = time.monotonic() + TIME_BUDGET
    for count in range(FRAMES_PER_FORMAT):
        frame = generate.frame()
        await client.send(frame)
        shown = repr(frame)[:300]
        assert await client.answers(), f"frame {count} (seed {SEED}) stalled or closed: {shown}"
        growth = server_memory(daphne_server) - base
        assert growth < MEMORY_BOUND, f"frame {count} grew the server by {growth}: {shown}"
        if time.monotonic() > give_up:
            break
    await client.close()
