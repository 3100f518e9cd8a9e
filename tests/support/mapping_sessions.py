"""Mapping sessions' helpers: a robot put online, the benchmark's tour as rosbridge
messages, a session read back, and waits for the session worker."""

from __future__ import annotations

import asyncio
import functools
from datetime import UTC, datetime
from typing import Any

from asgiref.sync import sync_to_async

from benchmarks.mapping import TourScan, drive_tour
from cloudnav_core.messages import pose_2d
from maps.models import MappingSession
from robots.agent.sim.changes import ChangeConfig, changed_demo_world, plan_changes
from robots.models import Robot, RobotState


def online(robot: Robot) -> None:
    RobotState.objects.update_or_create(
        robot=robot, defaults={"online": True, "last_seen": datetime.now(UTC), "x": 13.5, "y": 23.2}
    )


@functools.cache
def toured(seed: int = 0) -> list[TourScan]:
    """The scans of the benchmark's tour of the seed's new room (driven once a run)."""
    changes = plan_changes(seed, ChangeConfig(rooms=1))
    return drive_tour(seed, changes.rooms[0], changed_demo_world(changes))


def tour_messages(seed: int = 0) -> list[tuple[dict[str, Any], dict[str, Any]]]:
    return [({"pose": {"pose": pose_2d(*s.odom)}}, s.message) for s in toured(seed)]


def _session(pk: int) -> MappingSession:
    return MappingSession.objects.get(pk=pk)


async def _drained(worker: Any) -> None:
    """Let SLAM catch up with the scans given so far (a robot sends 10 a second)."""
    while worker.queue:  # noqa: ASYNC110 (the worker has no event for an empty queue)
        await asyncio.sleep(0.005)


async def _until(check: Any, seconds: float = 60.0) -> None:
    deadline = asyncio.get_running_loop().time() + seconds
    while not await sync_to_async(check)():
        assert asyncio.get_running_loop().time() < deadline, "never happened"
        await asyncio.sleep(0.1)
