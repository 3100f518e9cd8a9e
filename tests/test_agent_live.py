"""A robot on the network, as an operator's browser session meets it through a real daphne:
initial pose, goal and cancel (``/robot_0/cancel_goal``), teleop under the server's lock."""

from __future__ import annotations

import asyncio
import contextlib
import time
from collections.abc import AsyncIterator, Callable

import pytest
import websockets

from cloudnav_core.params import RobotConfig
from robots.agent.fleet import FleetOptions, FleetRobot, build_robot, run_fleet
from robots.agent.sim.world import demo_world
from tests.fixtures_live import LiveServer
from tests.support.agent_operator import (
    ACTIVE,
    CORRIDOR_A,
    PREEMPTED,
    ROBOT,
    START,
    Operator,
    pose,
    with_covariance,
)

pytestmark = pytest.mark.django_db(transaction=True)


@pytest.fixture
async def online(
    daphne_server: LiveServer, demo_token: str
) -> AsyncIterator[Callable[[float], FleetRobot]]:
    """``online(time_scale)``: the robot running in this process, connected to daphne."""
    running: list[asyncio.Task[None]] = []

    def start(time_scale: float) -> FleetRobot:
        options = FleetOptions(daphne_server.url, start=START, particles=200, robot=RobotConfig())
        member = build_robot(ROBOT, demo_token, demo_world(daphne_server.url), options)
        running.append(asyncio.create_task(run_fleet([member], time_scale)))
        return member

    yield start
    for task in running:
        task.cancel()
        with contextlib.suppress(asyncio.CancelledError):
            await task


async def test_an_operator_places_the_robot_sends_a_goal_and_cancels_it(
    daphne_server, operator_headers, online
):
    online(4.0)
    url = daphne_server.rosbridge_url()
    async with websockets.connect(url, additional_headers=operator_headers) as ws:
        operator = Operator(ws)
        for topic in ("pose", "nav_status", "map_id"):
            await operator.send(op="subscribe", topic=f"/{ROBOT}/{topic}")
        await operator.until(lambda: f"/{ROBOT}/nav_status" in operator.latest, "the robot")

        placed = with_covariance(pose(CORRIDOR_A, *START))
        await operator.send(op="publish", topic=f"/{ROBOT}/initialpose", msg=placed)
        await operator.until(lambda: f"/{ROBOT}/pose" in operator.latest, "a pose in a map")
        assert operator.latest[f"/{ROBOT}/map_id"] == {"data": f"{CORRIDOR_A}@v1"}
        assert operator.latest[f"/{ROBOT}/pose"]["header"]["frame_id"] == CORRIDOR_A

        await operator.send(op="publish", topic=f"/{ROBOT}/goal", msg=pose(CORRIDOR_A, 16, 23.2, 0))
        await operator.until(lambda: operator.last_status() == ACTIVE, "the goal taken")
        answer = await operator.call(f"/{ROBOT}/cancel_goal", {}, "cancel")
        assert answer["result"] is True
        assert answer["values"] == {"success": True, "message": "cancelled"}
        await operator.until(lambda: operator.last_status() == PREEMPTED, "PREEMPTED")


async def test_the_lock_holder_drives_it_and_it_stops_when_the_commands_stop(
    daphne_server, operator_headers, online
):
    online(1.0)  # real time: the operator's commands come at wall-clock pace
    url = daphne_server.rosbridge_url()
    async with websockets.connect(url, additional_headers=operator_headers) as ws:
        operator = Operator(ws)
        await operator.send(op="subscribe", topic=f"/{ROBOT}/odom")
        await operator.until(lambda: f"/{ROBOT}/odom" in operator.latest, "the robot")
        lock = await operator.call("/cloudnav/teleop_lock", {"robot": ROBOT}, "lock")
        assert lock["values"]["success"] is True
        go = {"linear": {"x": 0.9, "y": 0, "z": 0}, "angular": {"x": 0, "y": 0, "z": 0}}
        give_up = time.monotonic() + 10
        while operator.speed() < 0.45:  # beyond its limit: clamped to 0.5 m/s
            assert time.monotonic() < give_up, "it never drove"
            await operator.send(op="publish", topic=f"/{ROBOT}/cmd_vel", msg=go)
            await operator.read_for(0.1)
        assert operator.speed() <= 0.5 + 1e-6
        await operator.until(lambda: operator.speed() == 0.0, "a stop", deadline=5)
