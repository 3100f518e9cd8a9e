"""PostgreSQL down for 10 s under two server processes (a cluster of the test's own, stopped
as a crash): requests are answered 503 with Retry-After, not 500s; handshakes are refused;
sockets already open carry on; the log says so a few times, not once per request or loop
turn; service comes back by itself."""

from __future__ import annotations

import json
import time
import urllib.error
import urllib.request
from typing import Any

import pytest
import websockets.sync.client

from tests.fixtures_live import LiveServer, LiveServers, flush_redis, scaled_redis_url

pytestmark = [pytest.mark.scaled, pytest.mark.slow]

OUTAGE = 10.0
POSE: dict[str, Any] = {"header": {"frame_id": "boccioni_1/Hall"}, "pose": {"position": {"x": 1}}}
RECOVERY = 30.0  # a loaded 2-core machine; each request opens a new connection


def fleet(server: LiveServer, token: str) -> tuple[int, str | None]:
    """The status of a robot's ``GET /api/fleet/``, and its Retry-After."""
    request = urllib.request.Request(
        server.url + "/api/fleet/", headers={"Authorization": f"Token {token}"}
    )
    try:
        with urllib.request.urlopen(request, timeout=30) as response:
            return response.status, response.headers["Retry-After"]
    except urllib.error.HTTPError as error:
        return error.code, error.headers["Retry-After"]


def handshake_refused(server: LiveServer, token: str) -> bool:
    try:
        with websockets.sync.client.connect(server.rosbridge_url(token), open_timeout=30):
            return False
    except websockets.InvalidStatus:
        return True


def open_sockets(both: list[LiveServer], tokens: dict[str, str]) -> tuple[Any, Any]:
    """Robot r1 on process 0, and r2 on process 1 subscribed to r1's pose."""
    robot = websockets.sync.client.connect(both[0].rosbridge_url(tokens["r1"]), legacy=True)
    viewer = websockets.sync.client.connect(both[1].rosbridge_url(tokens["r2"]), legacy=True)
    viewer.send(json.dumps({"op": "subscribe", "topic": "/r1/pose"}))
    call = {"op": "call_service", "id": "sync", "service": "/rosapi/get_time"}
    viewer.send(json.dumps(call))  # answered once the subscription is in place
    assert json.loads(viewer.recv(timeout=30))["id"] == "sync"
    return robot, viewer


def test_postgresql_down_for_ten_seconds_answers_503_and_recovers(
    private_postgres, scaled_template, tmp_path
):
    token = scaled_template[1]["tokens"]["r1"]
    flush_redis(scaled_redis_url())
    servers = LiveServers(tmp_path, private_postgres.url)
    try:
        both = servers.start_many(2, env={"REDIS_URL": scaled_redis_url()})
        assert [fleet(server, token)[0] for server in both] == [200, 200]
        robot, viewer = open_sockets(both, scaled_template[1]["tokens"])
        logged = [server.log_lines() for server in both]

        private_postgres.stop()
        down_at, answers, refused, poses = time.monotonic(), set(), [], 0
        while time.monotonic() - down_at < OUTAGE:
            for server in both:
                answers.add(fleet(server, token))
            refused.append(handshake_refused(both[0], token))
            robot.send(json.dumps({"op": "publish", "topic": "pose", "msg": POSE}))
            poses += json.loads(viewer.recv(timeout=10))["msg"] == POSE
        private_postgres.start()
        assert poses == len(refused)  # open sockets carried on

        assert answers == {(503, "5")}
        assert all(refused)
        give_up = time.monotonic() + RECOVERY
        for server in both:
            while fleet(server, token)[0] != 200:
                assert time.monotonic() < give_up, "the server did not recover"
                time.sleep(0.2)
        assert not handshake_refused(both[1], token)
        for server, since in zip(both, logged, strict=True):
            assert len(server.told_since(since)) <= 10, server.log()
        robot.close()
        viewer.close()
    finally:
        servers.stop_all()
