"""SIGTERM to a daphne whose every kind of worker is busy: the process exits cleanly
within 10 s and leaves nothing half written (over real sockets against daphne).

Busy at once: a robot publishing poses and scans (the recorder, map upkeep and the mapping
runner tap them), a video viewer (the encoders), keyframes posted (ingestion) and a
relocalisation asked for (its threads)."""

from __future__ import annotations

import asyncio
import contextlib
import io
import json
import signal
import time
from pathlib import Path
from typing import Any

import httpx
import pytest
import websockets
from django.core.management import call_command
from mcap.reader import make_reader

from cloudnav_core.messages import compressed_image
from maps.models import Building
from robots.agent.hardware import encode_jpeg
from robots.agent.sim.camera import Camera as SimCamera
from robots.agent.sim.world import demo_world
from telemetry.recording import files
from tests.conftest import make_robot
from tests.support.camera_streams import watch
from tests.support.keyframes import SURVEY, WAKE_UP, keyframe_body
from tests.support.robot_messages import pose, scan

pytestmark = pytest.mark.django_db(transaction=True)

EXIT_WITHIN = 10.0
KEYFRAMES = "/api/buildings/boccioni_1/maps/CorridorA/keyframes"


@pytest.fixture
def token(transactional_db: None) -> str:
    call_command("seed_demo", stdout=io.StringIO())
    return make_robot(name="r1", buildings=[Building.objects.get(code="boccioni_1")])[1]


async def publish_until(url: str, stop: asyncio.Event) -> None:
    """Publish poses and scans as a navigating robot does, until ``stop`` (or the server
    goes)."""
    with contextlib.suppress(websockets.ConnectionClosed, OSError):
        async with websockets.connect(url) as ws:
            await ws.send(json.dumps({"op": "publish", "topic": "map_id", "msg": {"data": "x"}}))
            i = 0
            while not stop.is_set():
                await ws.send(json.dumps({"op": "publish", "topic": "pose", "msg": pose(i)}))
                await ws.send(json.dumps({"op": "publish", "topic": "scan", "msg": scan(i)}))
                i += 1
                await asyncio.sleep(0.01)


def post_keyframes(base: str, token: str) -> None:
    camera = SimCamera(demo_world(seed=0))
    with httpx.Client(base_url=base, headers=_robot(token), timeout=30) as client:
        for spot in SURVEY:
            assert client.post(KEYFRAMES, json=keyframe_body(camera, spot)).status_code == 202


def ask_relocalisation(base: str, token: str) -> None:
    """Ask where the robot is (answered, or cut off by the end)."""
    image = compressed_image(
        "camera", encode_jpeg(SimCamera(demo_world(seed=0), seed=9).render(WAKE_UP)), 2.0
    )
    with contextlib.suppress(httpx.HTTPError):
        httpx.post(
            f"{base}/api/relocalise", json={"images": [image]}, headers=_robot(token), timeout=30
        )


def _robot(token: str) -> dict[str, str]:
    return {"Authorization": f"Token {token}"}


def read_to_the_end(path: Path) -> int:
    with path.open("rb") as f:
        return sum(1 for _ in make_reader(f).iter_messages())


async def test_sigterm_with_every_kind_of_worker_busy_exits_cleanly_and_writes_whole_files(
    daphne_servers: Any, token: str, tmp_path: Path
) -> None:
    root = tmp_path / "recordings"
    server = daphne_servers.start(
        env={"CLOUDNAV_RECORDING_DIR": str(root), "CLOUDNAV_KEYFRAME_DIR": str(tmp_path / "kf")}
    )
    stop = asyncio.Event()
    robot = asyncio.create_task(publish_until(server.rosbridge_url(token), stop))
    camera, stream = await watch(server, token, "vp8")
    asking = asyncio.create_task(asyncio.to_thread(ask_relocalisation, server.url, token))
    await asyncio.to_thread(post_keyframes, server.url, token)
    deadline = time.monotonic() + 20
    while not files.files_of(root, "r1"):  # the recorder is writing
        assert time.monotonic() < deadline, server.log()
        await asyncio.sleep(0.05)
    await asyncio.sleep(0.5)

    server.process.send_signal(signal.SIGTERM)
    sent = time.monotonic()
    code = await asyncio.to_thread(server.process.wait, EXIT_WITHIN + 5)
    took = time.monotonic() - sent
    stop.set()
    stream.close()
    with contextlib.suppress(Exception):
        await camera.close()
    await asyncio.gather(robot, asking, return_exceptions=True)

    log = server.log()
    assert code == 0, log
    assert took < EXIT_WITHIN, log
    assert "Traceback" not in log
    [stopping] = [line for line in log.splitlines() if "shutdown: stopping" in line]
    for kind in ("recorder", "upkeep", "mapping", "video", "keyframes", "relocalise"):
        assert kind in stopping, stopping
    recordings = files.files_of(root, "r1")
    assert recordings
    for recording in recordings:
        assert files.finished(recording.path), recording.path
        assert read_to_the_end(recording.path) > 0
