"""The ROS 2 bridge node: bytes/s it sends the cloud, its CPU, tag read to /map and LoadMap.

On stock rclpy (the virtualenv ``scripts/ros2_env.sh --distro`` builds, Jazzy unless
told) in a ROS domain of its own, and a scratch server seeded with the demo building, the
simulated ROS 2 robot (``python -m robots.agent.sim.ros2_robot body``, ``nav2`` and
``watch``: the body, the Nav2 stand-in with its ``LoadMap``, a transient-local ``/map``
subscriber) stands before the entrance tag and ``python -m robots.agent.ros2`` (the
bridge, its defaults plus ``--load-map /map_server/load_map``) is started ``--samples``
times. Each time it reads the tag, fetches the sub-map's bundle, puts it on ``/map`` and
asks ``LoadMap`` to load its files: the time from its log line ``tag N read`` to the
watcher holding the map, and to the bridge's log line of ``LoadMap``'s answer, are one
sample each (the bundle's download included). The last bridge then runs ``--duration``
seconds after ``--warmup``, localised and standing: the bytes it sends the server and its
CPU over that window, measured as ``ros-bridge`` measures the ROS 1 bridge.
"""

from __future__ import annotations

import argparse
import itertools
import json
import os
import re
import subprocess
import tempfile
import time
from pathlib import Path
from typing import Any

from benchmarks import ros_bridge
from benchmarks.agent import ROOT, demo_server
from benchmarks.ros_bridge import TAG_READ, logged_at, measured_window, node, summary

NAME = "ros2-bridge"
LOADED = re.compile(r"^(\d{4}-\d\d-\d\d \d\d:\d\d:\d\d,\d{3}) \S+ load_map \S+: loaded")
DEADLINE = 240.0
"""Seconds a bridge may take to read the tag and put its sub-map on /map and LoadMap."""
DOMAINS = itertools.count(os.getpid() % 50 + 1)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--distro", choices=("jazzy", "kilted"), default="jazzy")
    ros_bridge.add_arguments(parser)


def run(options: dict[str, Any]) -> None:
    result = measure(options)
    print(json.dumps(result) if options["json"] else table(result))


def table(result: dict[str, Any]) -> str:
    delays = {"tag_to_map_ms": "/map", "tag_to_load_map_ms": "LoadMap answer"}
    return "\n".join(ros_bridge.table_rows(result, delays))


def ros2_venv(distro: str) -> Path:
    """The distro's ROS 2 virtualenv, built by ``scripts/ros2_env.sh`` when not cached.
    Raises RuntimeError (with the build's output) when it cannot be built."""
    built = subprocess.run(
        ["bash", str(ROOT / "scripts" / "ros2_env.sh"), distro],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=3600,
    )
    if built.returncode != 0:
        raise RuntimeError(f"scripts/ros2_env.sh {distro}:\n{built.stderr[-4000:]}")
    return Path(built.stdout.strip().splitlines()[-1])


def graph_env(venv: Path, domain: int | None = None) -> dict[str, str]:
    """The environment of a ROS 2 graph in ``venv``: ``domain``, else a domain of its own
    (one per call), discovery on this machine only, the repository on the path."""
    return {
        "PATH": f"{venv / 'bin'}:/usr/bin:/bin",
        "HOME": os.environ.get("HOME", "/tmp"),
        "PYTHONPATH": str(ROOT),
        "ROS_DOMAIN_ID": str(domain if domain is not None else next(DOMAINS) % 100 + 1),
        "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST",
    }


def measure(options: dict[str, Any]) -> dict[str, Any]:
    venv = ros2_venv(options["distro"])
    env, python = graph_env(venv), str(venv / "bin" / "python")
    server_options = {"url": None, "tokens_file": None, "robots": 1}
    with (
        demo_server(server_options) as (url, tokens),
        tempfile.TemporaryDirectory(prefix="cloudnav-ros2-bench-") as scratch,
    ):
        token, here = next(iter(tokens.values())), Path(scratch)
        robot = ["robots.agent.sim.ros2_robot"]
        body = ["body", "--cloud", url, "--seed", str(options["seed"])]
        watched, started = here / "watch.jsonl", here / "body.jsonl"
        body += ["--events", str(started)]
        with (
            node(env, here / "body.log", *robot, *body, python=python),
            node(env, here / "nav2.log", *robot, "nav2", python=python),
            node(env, here / "watch.log", *robot, "watch", "--events", str(watched), python=python),
        ):
            _wait_for_events(started)  # the body publishes before the bridges look
            return _measured(env, python, url, token, here, watched, options)


def _measured(
    env: dict[str, str],
    python: str,
    url: str,
    token: str,
    scratch: Path,
    watched: Path,
    options: dict[str, Any],
) -> dict[str, Any]:
    bridge = ["robots.agent.ros2", "--server", url, "--token", token]
    bridge += ["--load-map", "/map_server/load_map", "--map-dir", str(scratch / "maps")]
    to_map, to_loaded = [], []
    for sample in range(options["samples"]):
        log = scratch / f"bridge-{sample}.log"
        with node(env, log, *bridge, python=python) as process:
            mapped, loaded = _tag_to_map_and_load(log, watched, process)
            to_map.append(mapped)
            to_loaded.append(loaded)
            if sample == options["samples"] - 1:
                time.sleep(options["warmup"])
                window = measured_window(process.pid, url, options["duration"])
    return {
        **window,
        "distro": options["distro"],
        "tag_to_map_ms": summary(to_map),
        "tag_to_load_map_ms": summary(to_loaded),
    }


def _tag_to_map_and_load(
    log: Path, watched: Path, process: subprocess.Popen[bytes]
) -> tuple[float, float]:
    """Milliseconds from the bridge's ``tag N read`` to the next ``/map`` the watcher
    holds, and to the bridge's ``LoadMap`` answer."""
    seen, give_up = len(_maps(watched)), time.monotonic() + DEADLINE
    while (
        len(_maps(watched)) == seen
        or logged_at(log, TAG_READ) is None
        or logged_at(log, LOADED) is None
    ):
        if time.monotonic() > give_up or process.poll() is not None:
            raise RuntimeError(f"no tag read, /map and LoadMap:\n{log.read_text(errors='replace')}")
        time.sleep(0.05)
    read, loaded = logged_at(log, TAG_READ), logged_at(log, LOADED)
    assert read is not None
    assert loaded is not None
    # The watcher stamps with the monotonic clock, the bridge's log with the wall clock.
    mapped = _maps(watched)[seen] + (time.time() - time.monotonic())
    return (mapped - read) * 1000, (loaded - read) * 1000


def _wait_for_events(path: Path) -> None:
    """Until the node writing ``path`` says it is ready (``DEADLINE`` seconds at most)."""
    give_up = time.monotonic() + DEADLINE
    while not (path.exists() and '"ready"' in path.read_text()):
        if time.monotonic() > give_up:
            raise RuntimeError(f"{path.stem} never became ready")
        time.sleep(0.1)


def _maps(watched: Path) -> list[float]:
    """When (monotonic seconds) each map reached the watcher."""
    if not watched.exists():
        return []
    lines = (json.loads(line) for line in watched.read_text().splitlines() if line.endswith("}"))
    return [event["t"] for event in lines if event["event"] == "map"]
