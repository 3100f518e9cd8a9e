"""An idle fleet keeps the log quiet: a check that finds nothing changed (a robot's bundle
check, a page's open-alert count answered 304) is not logged at INFO, by the server or
the robot; what changed still is. Counted over a window on a real server and robot."""

from __future__ import annotations

import time
from pathlib import Path

import httpx
import pytest
from django.contrib.auth.models import User

from tests.fixtures_live import (
    ACCESS_LOG_ALL,
    LiveServer,
    LiveServers,
    agent_process,
    session_cookie,
    wait_for,
)

pytestmark = pytest.mark.django_db(transaction=True)

BUNDLE = "/api/buildings/boccioni_1/maps/CorridorA/bundle"
WINDOW = 20.0  # wall seconds of an idle robot counted
CHECKS_IN_WINDOW = 3  # at least, every 2 s of the robot's clock, on a loaded machine


def lines(log: Path) -> list[str]:
    return log.read_text(errors="replace").splitlines()


def test_unchanged_checks_are_not_logged_and_changes_are(
    daphne_server: LiveServer, demo_token: str
) -> None:
    operator = session_cookie(User.objects.get(username="operator")).decode()
    before = len(lines(daphne_server.log_path))
    with httpx.Client(base_url=daphne_server.url) as http:
        robot = {"Authorization": f"Token {demo_token}"}
        first = http.get(BUNDLE, headers=robot)
        person = {"Cookie": operator}
        count = http.get("/api/alerts/open", headers=person)
        for _ in range(5):
            again = http.get(BUNDLE, headers={**robot, "If-None-Match": first.headers["ETag"]})
            assert again.status_code == 304
            polled = {**person, "If-None-Match": count.headers["ETag"]}
            assert http.get("/api/alerts/open", headers=polled).status_code == 304
    wait_for(lambda: len(lines(daphne_server.log_path)) >= before + 2, 10, "no access log")
    time.sleep(0.5)  # anything more the server would have written
    written = lines(daphne_server.log_path)[before:]
    assert [line.split('"')[1] for line in written] == [f"GET {BUNDLE}", "GET /api/alerts/open"]
    assert all('" 200 ' in line for line in written)


def test_an_idle_robot_writes_nothing_to_either_log_at_info(
    daphne_servers: LiveServers, demo_token: str, tmp_path: Path
) -> None:
    # The server logs its access at DEBUG too, to count the robot's checks it answered.
    server = daphne_servers.start(env=ACCESS_LOG_ALL)
    with agent_process(server.url, demo_token, tmp_path / "agent.log") as agent_log:
        wait_for(
            lambda: f'"GET {BUNDLE}" 200' in server.log(),
            90,
            "the robot never fetched its first bundle",
        )
        time.sleep(2.0)  # its first words after the download (localised)
        server_before, agent_before = len(lines(server.log_path)), len(lines(agent_log))
        time.sleep(WINDOW)
        server_lines = lines(server.log_path)[server_before:]
        agent_lines = lines(agent_log)[agent_before:]
    checks = [line for line in server_lines if f'"GET {BUNDLE}" 304' in line]
    assert len(checks) >= CHECKS_IN_WINDOW, "the robot stopped checking its bundle"
    assert all(" DEBUG cloudnav_web.access: " in line for line in checks)
    assert [line for line in server_lines if " DEBUG " not in line] == []
    assert agent_lines == []
