"""Unmodified roslib 2.x (npm, ESM) under Node 20 against the live server.

The scenarios live in ``tests/js/roslib_scenarios.mjs``; each runs in its own ``node``
process and prints what it found as JSON. They need ``npm ci`` (roslib, ws) and Node 20.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from tests.fixtures_live import client_scenarios

ROOT = Path(__file__).resolve().parent.parent
SCRIPT = ROOT / "tests" / "js" / "roslib_scenarios.mjs"
POSE = {"header": {"frame_id": "boccioni_1/Hall"}, "pose": {"position": {"x": 1, "y": 2}}}


@pytest.fixture
def node() -> str:
    """The ``node`` executable; the test fails (never skips) without Node or ``npm ci``."""
    executable = shutil.which("node")
    assert executable is not None, "Node 20 is needed: install nodejs"
    assert (ROOT / "node_modules" / "roslib").exists(), "roslib is missing: run `npm ci`"
    return executable


@pytest.fixture
def run(node, daphne_server, building, operator):
    return client_scenarios([node, str(SCRIPT)], daphne_server, building, operator)


def test_roslib_subscribes_in_json_and_cbor_to_what_a_robot_publishes(run):
    found = run("pubsub")
    assert found["plain"] == POSE
    assert found["cbor"] == POSE


def test_roslib_rosapi_calls_work(run):
    found = run("rosapi")
    assert "/r1/map_id" in found["topics"]["topics"]
    assert "std_msgs/String" in found["topics"]["types"]
    assert "/cloudnav/teleop_lock" in found["services"]
    assert "/r1" in found["nodes"]
    assert found["param"] == 0.5
    assert found["time"]["time"]["sec"] > 1_700_000_000


def test_roslib_calls_a_cloud_service(run):
    assert run("cloud_service")["response"]["success"] is True


def test_roslib_advertises_and_answers_a_service(run):
    found = run("advertised_service")
    assert found["requests"] == [{"data": True}]
    assert found["response"] == {"success": True, "message": "docked"}


def test_roslib_sends_an_action_goal_and_gets_feedback(run):
    found = run("action")
    assert found["goals"] == [{"pose": POSE}]
    assert found["feedback"] == [{"distance_remaining": 2.0}]
    assert found["result"] == {"reached": True}
