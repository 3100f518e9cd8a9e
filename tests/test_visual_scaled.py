"""Scaled mode: a robot sends its keyframes to one server process, and relocalisation
asked on another gives the same answer, over REST and as the rosbridge service; an admin
clearing the sub-map on one process empties the map the other answers from.

Two daphne processes share PostgreSQL, Redis and the keyframe directory (the files are
where every process reads them, as a shared volume would hold them in production)."""

from __future__ import annotations

import asyncio
import json
import math
import time
from pathlib import Path
from typing import Any

import httpx
import pytest
import websockets

from cloudnav_core.messages import compressed_image
from robots.agent.hardware import encode_jpeg
from robots.agent.sim.camera import Camera
from robots.agent.sim.world import demo_world
from robots.agent.visual import keyframe_document
from tests.fixtures_live import run_manage
from tests.support.keyframes import SURVEY, WAKE_UP

pytestmark = [pytest.mark.scaled, pytest.mark.slow]

KEYFRAMES = "/api/buildings/boccioni_1/maps/CorridorA/keyframes"
DEADLINE = 120.0

# The demo building's sub-maps on the seeded building (the same code), and an admin of it.
SETUP = """
import io, sys, django
django.setup()
from django.core.management import call_command
from maps.models import Building
from tests.conftest import make_user
call_command("seed_demo", robots=0, tokens_file=sys.argv[1], stdout=io.StringIO())
Building.objects.get(code="boccioni_1").members.add(make_user("boss", "admin"))
"""


async def until(check: Any, what: str) -> Any:
    """Await ``check()`` until it answers something true; fail naming ``what``."""
    deadline = time.monotonic() + DEADLINE
    while not (found := await check()):
        assert time.monotonic() < deadline, f"timed out waiting for {what}"
        await asyncio.sleep(0.25)
    return found


async def send_survey(robot: httpx.AsyncClient) -> None:
    """Corridor A's keyframes, as the agent sends them (a full queue: try again)."""
    camera = Camera(demo_world(seed=0))
    for pose in SURVEY:
        image, depth = camera.capture(pose)
        assert depth is not None
        body = keyframe_document(camera.model, pose, image, depth)

        async def posted(body: Any = body) -> httpx.Response | None:
            answer = await robot.post(KEYFRAMES, json=body)
            return None if answer.status_code == 503 else answer

        answer = await until(posted, "room in the keyframe queue")
        assert answer.status_code == 202, answer.text


def wake_up_image() -> Any:
    image = Camera(demo_world(seed=0), seed=9).render(WAKE_UP)
    return compressed_image("camera", encode_jpeg(image), 2.0)


async def relocalise_over_rosbridge(url: str, question: dict[str, Any]) -> dict[str, Any]:
    async with websockets.connect(url) as socket:
        call = {"op": "call_service", "id": "where", "service": "/cloudnav/relocalise"}
        await socket.send(json.dumps({**call, "args": question}))
        while (reply := json.loads(await asyncio.wait_for(socket.recv(), 60)))["op"] != (
            "service_response"
        ):
            pass
    assert reply["result"] is True, reply
    return dict(reply["values"])


async def test_keyframes_sent_to_one_process_place_a_robot_asking_another(
    scaled_servers: Any, tmp_path: Path
) -> None:
    cluster = scaled_servers(2, env={"CLOUDNAV_KEYFRAME_DIR": str(tmp_path / "keyframes")})
    await asyncio.to_thread(
        run_manage, cluster.database_url, "-c", SETUP, str(tmp_path / "tokens.json")
    )
    here, there = cluster.servers  # where the keyframes go, where the question is asked
    token = {"Authorization": f"Token {cluster.tokens['r1']}"}
    sender = httpx.AsyncClient(base_url=here.url, headers=token, timeout=60)
    asker = httpx.AsyncClient(base_url=there.url, headers=token, timeout=60)
    admin = httpx.AsyncClient(base_url=there.url, auth=("boss", "pw-boss"), timeout=60)
    async with sender, asker, admin:
        await send_survey(sender)

        async def stored() -> list[Any]:
            """The coverage once most keyframes are in and no more came for 2 s."""
            before = (await asker.get(KEYFRAMES)).json()["keyframes"]
            await asyncio.sleep(2.0)
            seen = (await asker.get(KEYFRAMES)).json()["keyframes"]
            return seen if len(seen) == len(before) >= 0.9 * len(SURVEY) else []

        coverage = await until(stored, "the keyframes, seen from the other process")
        assert len(list((tmp_path / "keyframes").rglob("*.npz"))) == len(coverage)
        question = {"images": [wake_up_image()], "building": "boccioni_1"}
        answer = (await asker.post("/api/relocalise", json=question)).json()
        assert answer["localised"], answer
        assert answer["map_id"] == "boccioni_1/CorridorA"
        assert math.hypot(answer["pose"]["x"] - WAKE_UP[0], answer["pose"]["y"] - WAKE_UP[1]) < 0.15
        assert set(answer["keyframes"]) <= {k["id"] for k in coverage}
        assert (await sender.post("/api/relocalise", json=question)).json() == answer
        on_rosbridge = await relocalise_over_rosbridge(
            there.rosbridge_url(token=cluster.tokens["r1"]), question
        )
        assert on_rosbridge == answer

        cleared = await admin.delete(KEYFRAMES)
        assert cleared.json() == {"removed": len(coverage)}
        after = (await sender.post("/api/relocalise", json=question)).json()
        assert after["localised"] is False
        assert after["reason"] == "no keyframes are stored for this building yet"
        assert not list((tmp_path / "keyframes").rglob("*.npz"))
