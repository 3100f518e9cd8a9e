"""Robot agent CPU: simulated robots in one process, driving the demo building, per robot.

The server runs as its own daphne process on a scratch SQLite database seeded by
``manage.py seed_demo`` (or ``--url`` with ``--tokens-file`` points at a running one
seeded so). This process runs ``--robots`` robots as ``python -m robots.agent --count``
does (one asyncio loop; body at 50 Hz, laser and controller at 10 Hz, tag detector at
5 Hz, particle filter, rosbridge publishing, JPEG frames at ``--camera-rate``), each sent
to Office 7 from the building's entrance, so they read tags, fetch bundles and drive.

It prints the process CPU over ``--duration`` wall seconds after ``--warmup``: per
robot as a share of one core, and per simulated second; and whether the robots kept
to ``--time-scale`` (a saturated process runs the simulation slower instead).
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import json
import os
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from benchmarks.rosbridge import free_port, wait_for_http
from cloudnav_core.params import RobotConfig
from robots.agent.fleet import FleetOptions, FleetRobot, add_robot_arguments, build_fleet, run_fleet

ROOT = Path(__file__).resolve().parent.parent
START_S = 120.0
"""Seconds a scratch server may take to answer (a loaded machine starts it slowly)."""
OFFICE_7 = {
    "header": {"frame_id": "boccioni_1/Office7"},
    "pose": {"position": {"x": 47.7, "y": 27.5, "z": 0.0}, "orientation": {"w": 1.0}},
}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--robots", type=int, default=4, help="robots in the process")
    parser.add_argument("--duration", type=float, default=30.0, help="wall seconds measured")
    parser.add_argument("--warmup", type=float, default=5.0, help="wall seconds before")
    add_robot_arguments(parser)
    parser.add_argument("--url", help="a running server's http:// base instead of starting one")
    parser.add_argument("--tokens-file", help="with --url: seed_demo's tokens JSON")


def run(options: dict[str, Any]) -> None:
    with demo_server(options) as (url, tokens):
        result = asyncio.run(measure(url, tokens, options))
    print(report(result))


@dataclass(frozen=True)
class Result:
    robots: int
    wall: float
    cpu: float
    simulated: float  # simulated seconds, summed over robots
    time_scale: float

    @property
    def per_robot(self) -> float:
        """Share of one core per robot."""
        return self.cpu / self.wall / self.robots

    @property
    def kept_up(self) -> float:
        """Simulated time achieved over simulated time asked for."""
        return self.simulated / (self.wall * self.time_scale * self.robots)


def report(result: Result) -> str:
    return (
        f"{result.robots} robot(s), {result.wall:.0f} s at {result.time_scale:g}x: "
        f"CPU {100 * result.per_robot:.1f} % of a core per robot, "
        f"{1000 * result.cpu / result.simulated:.0f} ms per simulated second per robot; "
        f"simulation kept {100 * result.kept_up:.0f} % of the asked pace"
    )


# ---------------------------------------------------------------- the measurement


async def measure(url: str, tokens: dict[str, str], options: dict[str, Any]) -> Result:
    pairs = list(tokens.items())[: options["robots"]]
    robot_config = RobotConfig(camera_rate=options["camera_rate"], local_planner=options["planner"])
    fleet_options = FleetOptions(
        url,
        particles=options["particles"],
        robot=robot_config,
        people=options["people"],
        people_seed=options["people_seed"],
    )
    fleet = build_fleet(pairs, fleet_options)
    running = asyncio.create_task(run_fleet(fleet, options["time_scale"]))
    await asyncio.sleep(0.5)  # connected and subscribed
    for member in fleet:
        member.robot.on_goal(OFFICE_7)
    await asyncio.sleep(options["warmup"])
    simulated, cpu, wall = _now(fleet)
    await asyncio.sleep(options["duration"])
    simulated_end, cpu_end, wall_end = _now(fleet)
    running.cancel()
    with contextlib.suppress(asyncio.CancelledError):
        await running
    return Result(
        len(fleet), wall_end - wall, cpu_end - cpu, simulated_end - simulated, options["time_scale"]
    )


def _now(fleet: list[FleetRobot]) -> tuple[float, float, float]:
    """Simulated seconds of all robots, this process's CPU seconds, wall seconds."""
    return sum(m.robot.seconds for m in fleet), time.process_time(), time.monotonic()


# ---------------------------------------------------------------- the server


@contextlib.contextmanager
def demo_server(options: dict[str, Any]) -> Iterator[tuple[str, dict[str, str]]]:
    """``(http base, robot tokens)`` of a running server: ``--url``'s, or daphne on a
    scratch database seeded with the demo building, stopped at the end."""
    if options["url"]:
        yield options["url"], json.loads(Path(options["tokens_file"]).read_text())
        return
    with tempfile.TemporaryDirectory(prefix="cloudnav-agent-bench-") as scratch:
        env = {
            **os.environ,
            "DJANGO_SETTINGS_MODULE": "cloudnav_web.settings",
            "CLOUDNAV_DEMO": "1",  # a scratch server of the demo building
            "DATABASE_URL": f"sqlite:///{scratch}/bench.sqlite3",
            "REDIS_URL": "",
        }
        tokens = _seeded(env, Path(scratch) / "tokens.json", options["robots"])
        port = free_port()
        server = _daphne(env, port)
        try:
            wait_for_http(f"http://127.0.0.1:{port}/", server, deadline=START_S)
            print(f"server pid {server.pid} on port {port}", file=sys.stderr)
            yield f"http://127.0.0.1:{port}", tokens
        finally:
            _stop(server)


def _seeded(env: dict[str, str], tokens: Path, robots: int) -> dict[str, str]:
    manage = [sys.executable, "manage.py"]
    subprocess.run([*manage, "migrate", "-v0"], cwd=ROOT, env=env, check=True)
    seed = ["seed_demo", "--robots", str(robots), "--tokens-file", str(tokens)]
    subprocess.run([*manage, *seed], cwd=ROOT, env=env, check=True, capture_output=True)
    return dict(json.loads(tokens.read_text()))


def _daphne(env: dict[str, str], port: int) -> subprocess.Popen[bytes]:
    command = [sys.executable, "-m", "daphne", "-b", "127.0.0.1", "-p", str(port)]
    return subprocess.Popen(
        [*command, "--access-log", os.devnull, "cloudnav_web.asgi:application"],
        cwd=ROOT,
        env=env,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )


def _stop(server: subprocess.Popen[bytes]) -> None:
    if server.poll() is None:
        server.terminate()
        with contextlib.suppress(subprocess.TimeoutExpired):
            server.wait(10)
    if server.poll() is None:
        server.kill()
        server.wait(10)
