"""``manage.py bench video`` runs end to end (a short run against a live server; the
figures themselves are not tested, the bench prints them)."""

from __future__ import annotations

import io
from contextlib import redirect_stdout

import pytest
from django.test import Client

from benchmarks import video
from tests.conftest import make_building, make_robot

pytestmark = [pytest.mark.django_db(transaction=True), pytest.mark.slow]


def test_it_prints_bandwidth_frames_delay_and_cpu_per_stream_type(daphne_server, viewer):
    _, token = make_robot(name=video.ROBOT, buildings=[make_building(members=[viewer])])
    client = Client()
    client.force_login(viewer)
    options = {
        "width": 160,
        "height": 120,
        "rate": 20.0,
        "duration": 1.5,
        "warmup": 0.5,
        "viewers": 2,
        "quality": None,
        "camera_quality": 90,
        "types": "mjpeg,vp8",
        "url": daphne_server.url,
        "token": token,
        "cookie": f"sessionid={client.cookies['sessionid'].value}",
        "server_pid": daphne_server.process.pid,
    }
    printed = io.StringIO()
    with redirect_stdout(printed):
        video.run(options)
    rows = {line.split()[0]: line.split() for line in printed.getvalue().splitlines()[2:]}
    assert set(rows) == {"mjpeg", "vp8"}
    for row in rows.values():
        delivered, published = row[4].split("/")
        assert int(published) > 0
        fewest = int(delivered.split("..")[0])
        # Most frames, whatever the machine's load (the full run's target is every frame).
        assert fewest >= 0.5 * int(published)
