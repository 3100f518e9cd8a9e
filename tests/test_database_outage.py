"""PostgreSQL down for 10 s under two server processes (a cluster of the test's own, stopped
as a crash): requests are answered 503 with Retry-After, not 500s; handshakes are
refused; the log says so a few times, not once per request; service comes back by itself."""

from __future__ import annotations

import time
import urllib.error
import urllib.request

import pytest
import websockets.sync.client

from tests.fixtures_live import LiveServer, LiveServers, flush_redis, scaled_redis_url

pytestmark = [pytest.mark.scaled, pytest.mark.slow]

OUTAGE = 10.0
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


def not_access_lines(server: LiveServer, since: int) -> list[str]:
    lines = server.log().splitlines()[since:]
    return [line for line in lines if "cloudnav_web.access" not in line]


def test_postgresql_down_for_ten_seconds_answers_503_and_recovers(
    private_postgres, scaled_template, tmp_path
):
    token = scaled_template[1]["tokens"]["r1"]
    flush_redis(scaled_redis_url())
    servers = LiveServers(tmp_path, private_postgres.url)
    try:
        both = servers.start_many(2, env={"REDIS_URL": scaled_redis_url()})
        assert [fleet(server, token)[0] for server in both] == [200, 200]
        logged = [len(server.log().splitlines()) for server in both]

        private_postgres.stop()
        down_at, answers, refused = time.monotonic(), set(), []
        while time.monotonic() - down_at < OUTAGE:
            for server in both:
                answers.add(fleet(server, token))
            refused.append(handshake_refused(both[0], token))
        private_postgres.start()

        assert answers == {(503, "5")}
        assert all(refused)
        give_up = time.monotonic() + RECOVERY
        for server in both:
            while fleet(server, token)[0] != 200:
                assert time.monotonic() < give_up, "the server did not recover"
                time.sleep(0.2)
        assert not handshake_refused(both[1], token)
        for server, since in zip(both, logged, strict=True):
            assert len(not_access_lines(server, since)) <= 10, server.log()
    finally:
        servers.stop_all()
