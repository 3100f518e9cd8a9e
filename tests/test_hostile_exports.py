"""Recording exports within budget (issue 23 point 12): one person's parallel exports past
their share get 429, and a big export is made as its client reads it, so the server holds
a few chunks of it at a time, never the whole file (Django reads a plain iterator to its
end before sending it under ASGI; daphne buffers whatever it is given).
"""

from __future__ import annotations

import http.client
import time
import tracemalloc
from pathlib import Path

import psutil
import pytest
from django.contrib.auth.models import User

from maps.models import Building
from telemetry.domain import ros1
from telemetry.recording import export, files
from tests.conftest import client_for, make_robot
from tests.fixtures_live import LiveServers
from tests.support.uploads import basic

NS = 1_000_000_000
IMAGE = "sensor_msgs/CompressedImage"
BIG_EXPORT_BYTES = 160 * 2**20
MEMORY_BOUND = 48 * 2**20


def record_images(root: Path, robot: str, total_bytes: int, size: int = 2**20) -> None:
    """``total_bytes`` of incompressible camera images, one a second from t = 1000 s."""
    writer = files.RotatingFiles(root, robot, max_seconds=60, max_bytes=2**30)
    schema = ros1.schema_text(IMAGE).encode()
    random = open("/dev/urandom", "rb")  # noqa: SIM115
    with random:
        for second in range(total_bytes // size):
            msg = {"header": {"frame_id": "cam"}, "format": "jpeg", "data": random.read(size)}
            data = ros1.encode(IMAGE, msg)
            record = files.Record(f"/{robot}/camera", IMAGE, schema, (1000 + second) * NS, data)
            writer.write(record)
    writer.close()


@pytest.fixture
def big_recording(settings, tmp_path: Path, building: Building) -> Path:
    settings.CLOUDNAV_RECORDING_DIR = tmp_path
    make_robot(name="r1", buildings=[building])
    record_images(tmp_path, "r1", BIG_EXPORT_BYTES)
    return tmp_path


URL = "/api/robots/r1/recording.{kind}?start=1000&end=2000"


@pytest.mark.django_db
@pytest.mark.parametrize("kind", ["mcap", "bag"])
def test_a_persons_exports_past_their_share_get_429(
    settings, tmp_path: Path, building: Building, viewer: User, operator: User, kind: str
) -> None:
    settings.CLOUDNAV_RECORDING_DIR = tmp_path
    settings.CLOUDNAV_EXPORT_PER_CLIENT = 2
    make_robot(name="r1", buildings=[building])
    mine = [client_for(viewer).get(URL.format(kind=kind)) for _ in range(3)]
    assert [r.status_code for r in mine] == [200, 200, 429]
    assert "Retry-After" in mine[2]
    theirs = client_for(operator).get(URL.format(kind=kind))
    assert theirs.status_code == 200  # another person's share
    assert sent(mine[0])  # one sent: a share is free again
    again = client_for(viewer).get(URL.format(kind=kind))
    assert again.status_code == 200
    assert all(sent(response) for response in (mine[1], theirs, again))


def sent(response) -> bytes:
    """The whole body, as a client takes it (the export's share is then given back)."""
    return b"".join(response.streaming_content)


@pytest.mark.django_db
@pytest.mark.parametrize("kind", ["mcap", "bag"])
def test_an_export_holds_no_more_than_its_estimate_whatever_its_size(
    big_recording: Path, kind: str
) -> None:
    taken = export.snapshot(big_recording, ["r1"], 1000 * NS, 2000 * NS)
    if kind == "bag":
        pieces = export.bag_stream(lambda: export.snapshot_records(taken, 0, 2**62))
    else:
        pieces = export.mcap_stream(export.snapshot_records(taken, 0, 2**62))
    tracemalloc.start()
    try:
        sent = sum(len(piece) for piece in pieces)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert sent > BIG_EXPORT_BYTES
    assert peak < export.EXPORT_MEMORY_BYTES, peak


@pytest.mark.parametrize("kind", ["mcap", "bag"])
def test_a_big_export_to_a_slow_client_holds_little_server_memory(
    daphne_servers: LiveServers, big_recording: Path, viewer: User, kind: str
) -> None:
    server = daphne_servers.start(env={"CLOUDNAV_RECORDING_DIR": str(big_recording)})
    process = psutil.Process(server.process.pid)
    base = process.memory_info().rss
    connection = http.client.HTTPConnection(server.host, server.port, timeout=60)
    connection.request("GET", URL.format(kind=kind), headers=basic("viewer"))
    answer = connection.getresponse()
    assert answer.status == 200
    answer.read(2**20)
    # The client stops reading: the server may make only what the socket can take.
    peak, quiet_until = base, time.monotonic() + 3.0
    while time.monotonic() < quiet_until:
        peak = max(peak, process.memory_info().rss)
        time.sleep(0.02)
    received = 2**20
    while piece := answer.read(2**20):
        received += len(piece)
        peak = max(peak, process.memory_info().rss)
    connection.close()
    assert received > BIG_EXPORT_BYTES
    assert peak - base < MEMORY_BOUND, f"grew {(peak - base) / 2**20:.0f} MiB"
