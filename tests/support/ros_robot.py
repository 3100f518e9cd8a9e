"""Where the ROS robot tests drive in the demo building, the sub-maps' sizes, the grid the
cloud serves and the logs shown when a test fails; shared by the ROS 1 and ROS 2 tests."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from tests.support.agent_operator import CORRIDOR_A

ATRIUM_1 = "boccioni_1/Atrium1"
IN_ATRIUM_1 = (20.0, 23.8, 0.0)
BACK_IN_CORRIDOR_A = (14.0, 23.2, math.pi)
TAG_1_APPROACH = (17.3, 22.6)  # 0.5 m in front of tag 1, which leads to Atrium 1
SUCCEEDED = 3
SUB_MAP_SIZES = {CORRIDOR_A: (392, 160), ATRIUM_1: (232, 232)}  # width, height
TURNING = 0.4  # rad/s, the operator's teleop


def log_tails(directory: Path) -> str:
    """The end of each ``*.log`` (and of each node's ``*.jsonl`` events) in ``directory``,
    for a failure's message."""
    tails = [(p, 3000) for p in sorted(directory.glob("*.log"))]
    tails += [(p, 600) for p in sorted(directory.glob("*.jsonl"))]
    return "\n".join(f"--- {p.name}\n{p.read_text(errors='replace')[-size:]}" for p, size in tails)


async def cloud_grid(server: Any, token: str, map_id: str) -> Any:
    """The grid of ``map_id`` as the cloud serves it to the robot."""
    import httpx

    from robots.agent.supervisor.submaps import submap_from_bundle

    building, _, code = map_id.partition("/")
    async with httpx.AsyncClient(
        base_url=server.url, headers={"Authorization": f"Token {token}"}, timeout=30
    ) as http:
        answer = await http.get(f"/api/buildings/{building}/maps/{code}/bundle")
    assert answer.status_code == 200
    return submap_from_bundle(answer.json(), "").grid
