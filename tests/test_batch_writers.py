"""One bad string never stops a log (issue 23 point 11): text PostgreSQL refuses (a NUL,
a lone surrogate) is cleaned where it arrives, and a batch the database refuses is written
row by row, so no robot's event, alert or mission outcome is held back by another's."""

from __future__ import annotations

import asyncio
import json
import time
import urllib.request

import pytest
import websockets

from telemetry.domain.storable import storable, storable_text

pytestmark = pytest.mark.django_db(transaction=True)

# JSON as a robot sends it: a NUL, and a lone surrogate (neither is storable text)
BAD_TEXT = '"blocked\\u0000by \\ud800 a pallet"'


def aborted(text_json: str, goal: str) -> str:
    """A robot's ``nav_status`` frame: goal ``goal`` aborted with the reason ``text_json``."""
    status = f'{{"goal_id": {{"id": "{goal}"}}, "status": 4, "text": {text_json}}}'
    return f'{{"op": "publish", "topic": "nav_status", "msg": {{"status_list": [{status}]}}}}'


def events_of(live, cookie: str) -> list[dict]:
    request = urllib.request.Request(
        f"{live.url}/api/events/?kind=goal_aborted", headers={"Cookie": cookie}
    )
    with urllib.request.urlopen(request, timeout=5) as answer:
        return list(json.loads(answer.read()))


@pytest.mark.scaled
async def test_on_postgresql_a_nul_in_one_robots_text_holds_back_no_event(scaled_servers):
    cluster = scaled_servers(1)
    live = cluster.servers[0]
    async with (
        websockets.connect(live.rosbridge_url(cluster.tokens["r1"])) as r1,
        websockets.connect(live.rosbridge_url(cluster.tokens["r2"])) as r2,
    ):
        await r1.send(aborted(BAD_TEXT, "g1"))
        await r2.send(aborted('"no path"', "g2"))
        deadline = time.monotonic() + 10
        while True:
            found = await asyncio.to_thread(events_of, live, cluster.cookies["viewer"])
            by_robot = {e["robot"]: e for e in found}
            if {"r1", "r2"} <= by_robot.keys():
                break
            assert time.monotonic() < deadline, (found, live.log())
            await asyncio.sleep(0.1)
        await r2.send(aborted('"still no path"', "g3"))  # later events too
        while len(await asyncio.to_thread(events_of, live, cluster.cookies["viewer"])) < 3:
            assert time.monotonic() < deadline + 10, live.log()
            await asyncio.sleep(0.1)
    assert by_robot["r1"]["message"] == "r1: goal aborted: blocked\ufffdby \ufffd a pallet"
    assert by_robot["r1"]["data"]["reason"] == "blocked\ufffdby \ufffd a pallet"


def test_text_is_cleaned_of_what_no_database_stores_and_kept_otherwise():
    assert storable_text("a\x00b\ud800c") == "a\ufffdb\ufffdc"
    assert storable_text("Gänge 3") == "Gänge 3"
    assert storable({"k\x00": ["x\x00", 1, None, {"y": "\udfff"}]}) == {
        "k\ufffd": ["x\ufffd", 1, None, {"y": "\ufffd"}]
    }


OUTCOMES = """
import json, django
django.setup()
from maps.models import Building
from robots.models import Mission, Robot
from robots.missions import REACHED, record_outcomes
building = Building.objects.get()
point = {"map": "Hall", "x": 0.0, "y": 0.0, "yaw": 0.0}
made = {
    name: Mission.objects.create(
        building=building, robot=Robot.objects.get(name=name), waypoints=[point, point]
    )
    for name in ("r1", "r2")
}
record_outcomes({made["r1"].pk: "goal aborted: " + "blocked " * 100, made["r2"].pk: REACHED})
now = {name: Mission.objects.get(pk=m.pk) for name, m in made.items()}
print(json.dumps({name: [m.state, m.index, m.note] for name, m in now.items()}))
"""


@pytest.mark.scaled
def test_on_postgresql_a_long_reason_pauses_its_mission_and_the_others_go_on(scaled_servers):
    from tests.fixtures_live import run_manage

    database = scaled_servers(0).database_url  # the seeded PostgreSQL database, no server
    found = json.loads(run_manage(database, "-c", OUTCOMES).strip().splitlines()[-1])
    state, index, note = found["r1"]
    assert (state, index) == ("paused", 0)
    assert note.startswith("paused: goal aborted: blocked blocked")
    assert found["r2"][:2] == ["running", 1]


def test_a_robots_reason_with_a_nul_is_kept_as_storable_text():
    from robots.missions import Goal
    from telemetry.missions import MissionRunner, Sent

    async def as_placed(goal):
        return goal

    async def late(_goal):
        return None

    now = [0.0]
    runner = MissionRunner(
        lambda _goal: None, lambda: {"r1"}, as_placed, late, clock=lambda: now[0]
    )
    runner._sent["r1"] = Sent(Goal(7, "r1", "b/m", 0.0, 0.0, 0.0), 0.0)  # mission 7's, at 0 s
    now[0] = 5.0
    runner.status("r1", {"status_list": [{"status": 4, "text": "a\x00b\ud800"}]})
    assert runner._outcomes == {7: "goal aborted: a\ufffdb\ufffd"}
