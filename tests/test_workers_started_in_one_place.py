"""Every worker of the server process is started in one place, ``cloudnav_web.background``
(issue 24 point 4). Read from the source: no module makes a worker or a thread but the
known ones, and what starts each is called from there alone. Run: the workers serving
requests run before any request, and a daphne that served none of their requests has
every kind to stop when it ends (over real sockets against daphne)."""

from __future__ import annotations

import ast
import asyncio
import signal
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
import websockets

from cloudnav_core.workers import REGISTRY

ROOT = Path(__file__).resolve().parent.parent
PACKAGES = ("cloudnav_core", "cloudnav_django", "cloudnav_web", "maps", "robots", "telemetry")
ROBOT_SIDE = "robots.agent"  # runs on a robot, not in the server process
COMPOSITION_ROOT = "cloudnav_web.background"

WORKER_KINDS = frozenset({"Worker", "Pool", "TaskWorker", "Thread", "ThreadPoolExecutor"})
MAKERS = frozenset(
    {
        "maps.visual.worker",  # keyframe ingestion, in IngestQueue
        "maps.visual.lanes",  # the relocalisation threads, in RelocalisationLanes
        "telemetry.video.relay",  # the encoders, in start_encoders
        "telemetry.recording.recorder",  # the recorder, in Recorder
        "maps.mapping.runner",  # its pool; the runner and its sessions, in MappingRunner
        "maps.mapping.upkeep",  # its pool; map upkeep, in UpkeepRunner
    }
)
"""The modules that make workers (``cloudnav_core.workers`` makes the kinds)."""
STARTERS = {
    "IngestQueue": "maps.visual.worker",  # in start_ingestion
    "RelocalisationLanes": "maps.visual.lanes",  # in start_relocalisation
    "Recorder": "telemetry.recording.service",  # in start_recorder
    "start_ingestion": COMPOSITION_ROOT,
    "start_relocalisation": COMPOSITION_ROOT,
    "start_encoders": COMPOSITION_ROOT,
    "start_recorder": COMPOSITION_ROOT,
    "MappingRunner": COMPOSITION_ROOT,
    "UpkeepRunner": COMPOSITION_ROOT,
}
"""What makes or starts those workers, and the one module that calls it (besides the
module that defines it)."""


def server_modules() -> Iterator[tuple[str, ast.Module]]:
    for package in PACKAGES:
        for path in sorted((ROOT / package).rglob("*.py")):
            name = ".".join(path.relative_to(ROOT).with_suffix("").parts)
            if not name.startswith(ROBOT_SIDE):
                yield name, ast.parse(path.read_text(), str(path))


def called(tree: ast.Module) -> set[str]:
    """What the module calls, by name: ``f(...)`` and ``x.f(...)`` alike."""
    names = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Name):
            names.add(node.func.id)
        elif isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute):
            names.add(node.func.attr)
    return names


def defined(tree: ast.Module) -> set[str]:
    return {node.name for node in tree.body if isinstance(node, ast.FunctionDef | ast.ClassDef)}


@pytest.fixture(scope="module")
def modules() -> dict[str, tuple[set[str], set[str]]]:
    """What each server module calls and defines."""
    return {name: (called(tree), defined(tree)) for name, tree in server_modules()}


def test_only_the_known_modules_make_workers(modules: dict[str, tuple[set[str], set[str]]]) -> None:
    makers = {name for name, (calls, _) in modules.items() if calls & WORKER_KINDS}
    assert makers - {"cloudnav_core.workers"} == MAKERS, (
        "a module makes workers: start them from cloudnav_web.background, and name it here"
    )


def test_what_starts_each_worker_is_called_from_the_composition_root_alone(
    modules: dict[str, tuple[set[str], set[str]]],
) -> None:
    elsewhere = sorted(
        f"{starter} in {name}"
        for name, (calls, defines) in modules.items()
        for starter, caller in STARTERS.items()
        if starter in calls and name != caller and starter not in defines
    )
    assert not elsewhere, f"workers started outside {COMPOSITION_ROOT}: {elsewhere}"


def test_the_workers_serving_requests_run_before_any_request() -> None:
    # conftest's ``serving_workers`` started them, as the ASGI application does
    for name in ("keyframes", "relocalise-0", "relocalise-1", "video"):
        assert name in REGISTRY.names()


def stopped_at_the_end(log: str) -> set[str]:
    """The workers the shutdown stopped, as its log line names them."""
    [line] = [line for line in log.splitlines() if "shutdown: stopping " in line]
    return set(line.split("shutdown: stopping ", 1)[1].split(", "))


@pytest.mark.django_db(transaction=True)
async def test_a_daphne_that_served_none_of_their_requests_has_every_kind_to_stop(
    daphne_servers: Any, token: str, tmp_path: Path
) -> None:
    server = daphne_servers.start(env={"CLOUDNAV_RECORDING_DIR": str(tmp_path / "recordings")})
    async with websockets.connect(server.rosbridge_url(token)):
        pass  # accepted once the hub has started, and its workers with it
    server.process.send_signal(signal.SIGTERM)
    code = await asyncio.to_thread(server.process.wait, 15)
    log = server.log()
    assert code == 0, log
    stopped = stopped_at_the_end(log)  # thread workers: the tasks are cancelled before
    assert {"recorder", "mapping", "upkeep"} <= stopped, log  # with the hub, the pools before
    assert {"keyframes", "relocalise-0", "relocalise-1", "video"} <= stopped, log
