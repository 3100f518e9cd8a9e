"""The ROS 1 bridge node: bytes/s it sends the cloud, its CPU, tag read to /map.

On a private ``roscore`` (Debian's ROS 1) and a scratch server seeded with the demo
building, the simulated ROS robot (``python -m robots.agent.sim.ros_robot body`` and
``move_base``) stands before the entrance tag and ``python -m robots.agent.ros`` (the
bridge, its defaults: move_base navigation, pose from ``amcl_pose``, the fleet's default
rates) is started ``--samples`` times. Each time it reads the tag, fetches the sub-map's
bundle and puts it on ``/map``: the time from its log line ``tag N read`` to this
process's ``/map`` subscriber holding the map is one sample (the cloud's half, the
bundle's download, included). The last bridge then runs ``--duration`` seconds after
``--warmup``, localised and standing: the bytes it sends the server (TCP
``bytes_acked`` of its connections to daphne, ``ss -tin``) and its CPU (utime + stime of
``/proc/PID/stat``) over that window.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import re
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from datetime import datetime
from pathlib import Path
from typing import Any

from benchmarks.agent import ROOT, demo_server
from robots.agent.ros import ros_path

NAME = "ros-bridge"
TAG_READ = re.compile(r"^(\d{4}-\d\d-\d\d \d\d:\d\d:\d\d,\d{3}) \S+ tag \d+ read: entering")
ACKED = re.compile(r"bytes_acked:(\d+)")
DEADLINE = 180.0
"""Seconds a bridge may take to read the tag and put its sub-map on /map."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The options of both ROS bridges' benchmarks."""
    parser.add_argument("--samples", type=int, default=3, help="bridges started, tag reads")
    parser.add_argument("--duration", type=float, default=20.0, help="wall seconds measured")
    parser.add_argument("--warmup", type=float, default=5.0, help="wall seconds before")
    parser.add_argument("--seed", type=int, default=0, help="the simulated robot's noise")
    parser.add_argument("--json", action="store_true", help="print only the JSON object")


def run(options: dict[str, Any]) -> None:
    if not ros_path():
        raise SystemExit("ROS 1 is not installed (scripts/setup.sh installs it)")
    result = measure(options)
    print(json.dumps(result) if options["json"] else table(result))


def table(result: dict[str, Any]) -> str:
    return "\n".join(table_rows(result, {"tag_to_map_ms": "/map"}))


def table_rows(result: dict[str, Any], delays: dict[str, str]) -> list[str]:
    """The rows of a bridge's figures: bytes sent, CPU, and each of ``delays`` (the
    result's key of a ``summary``: what it measures to)."""
    rows = [
        f"sent per robot: {result['bytes_per_second']:.0f} B/s "
        f"({result['bytes']} bytes in {result['seconds']:.1f} s)",
        f"bridge CPU: {result['cpu_cores']:.3f} core",
    ]
    for key, what in delays.items():
        found = result[key]
        rows.append(
            f"tag read -> {what}: median {found['median']:.0f} ms, worst {found['worst']:.0f} ms"
            f" ({len(found['samples'])} samples)"
        )
    return rows


def measure(options: dict[str, Any]) -> dict[str, Any]:
    from robots.agent.ros.master import private_roscore

    server_options = {"url": None, "tokens_file": None, "robots": 1}
    with (
        demo_server(server_options) as (url, tokens),
        private_roscore() as env,
        tempfile.TemporaryDirectory(prefix="cloudnav-ros-bench-") as scratch,
    ):
        token = next(iter(tokens.values()))
        robot = ["robots.agent.sim.ros_robot"]
        body = ["body", "--cloud", url, "--seed", str(options["seed"])]
        with (
            node(env, Path(scratch, "body.log"), *robot, *body),
            node(env, Path(scratch, "move_base.log"), *robot, "move_base"),
        ):
            return _measured(env, url, token, Path(scratch), options)


def _measured(
    env: dict[str, str], url: str, token: str, scratch: Path, options: dict[str, Any]
) -> dict[str, Any]:
    import rospy  # type: ignore[import-not-found,unused-ignore]
    from nav_msgs.msg import OccupancyGrid  # type: ignore[import-not-found,unused-ignore]

    rospy.init_node("cloudnav_bench", disable_signals=True)
    arrivals: list[float] = []
    rospy.Subscriber("/map", OccupancyGrid, lambda _msg: arrivals.append(time.time()))
    bridge = ["robots.agent.ros", "--server", url, "--token", token]
    delays = []
    for sample in range(options["samples"]):
        log = scratch / f"bridge-{sample}.log"
        with node(env, log, *bridge) as process:
            delays.append(_tag_to_map(log, arrivals, process))
            if sample == options["samples"] - 1:
                time.sleep(options["warmup"])
                window = measured_window(process.pid, url, options["duration"])
    rospy.signal_shutdown("measured")
    return {**window, "tag_to_map_ms": summary(delays)}


def _tag_to_map(log: Path, arrivals: list[float], process: subprocess.Popen[bytes]) -> float:
    """Milliseconds from the bridge's ``tag N read`` to the next ``/map`` here."""
    seen, give_up = len(arrivals), time.monotonic() + DEADLINE
    while len(arrivals) == seen or logged_at(log, TAG_READ) is None:
        if time.monotonic() > give_up or process.poll() is not None:
            raise RuntimeError(f"no tag read and /map:\n{log.read_text(errors='replace')}")
        time.sleep(0.05)
    read = logged_at(log, TAG_READ)
    assert read is not None
    return (arrivals[seen] - read) * 1000


def logged_at(log: Path, line: re.Pattern[str]) -> float | None:
    """When (wall-clock seconds) the first line of ``log`` matching ``line`` was logged
    (its first group: the logging module's ``asctime``); None before one is."""
    for text in log.read_text(errors="replace").splitlines():
        found = line.match(text)
        if found:
            return datetime.strptime(found[1], "%Y-%m-%d %H:%M:%S,%f").timestamp()
    return None


def measured_window(pid: int, url: str, duration: float) -> dict[str, Any]:
    """Bytes process ``pid`` sends the server at ``url`` and its CPU, over ``duration``
    seconds."""
    port = int(url.rsplit(":", 1)[1])
    sent, cpu, wall = _acked(port), _cpu(pid), time.monotonic()
    time.sleep(duration)
    sent, cpu, wall = _acked(port) - sent, _cpu(pid) - cpu, time.monotonic() - wall
    return {
        "bytes": sent,
        "seconds": wall,
        "bytes_per_second": sent / wall,
        "cpu_cores": cpu / wall,
    }


def _acked(port: int) -> int:
    """Bytes acknowledged on every established connection to ``port`` (the bridge's)."""
    listing = subprocess.run(
        ["ss", "-tinH", "state", "established", f"( dport = :{port} )"],
        capture_output=True,
        text=True,
        check=True,
    ).stdout
    return sum(int(n) for n in ACKED.findall(listing))


def _cpu(pid: int) -> float:
    """CPU seconds (user + system) of process ``pid``."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def summary(delays: list[float]) -> dict[str, Any]:
    return {
        "median": statistics.median(delays),
        "worst": max(delays),
        "samples": [round(d, 1) for d in delays],
    }


def start_node(
    env: dict[str, str], log: Path, *command: str, python: str = sys.executable
) -> subprocess.Popen[bytes]:
    """``python -m <command>`` in ``env`` (a private roscore's, a ROS 2 domain's) with the
    repository on its path, its output in ``log``."""
    with log.open("wb") as out:
        return subprocess.Popen(
            [python, "-m", *command],
            env={**env, "PYTHONPATH": str(ROOT)},
            cwd=ROOT,
            stdout=out,
            stderr=subprocess.STDOUT,
        )


def stop_node(process: subprocess.Popen[Any]) -> None:
    """Terminate ``process``; killed if it has not ended 30 s later."""
    process.terminate()
    try:
        process.wait(timeout=30)
    except subprocess.TimeoutExpired:
        process.kill()
        process.wait(timeout=30)


@contextlib.contextmanager
def node(
    env: dict[str, str], log: Path, *command: str, python: str = sys.executable
) -> Iterator[subprocess.Popen[bytes]]:
    """``start_node``, stopped after."""
    process = start_node(env, log, *command, python=python)
    try:
        yield process
    finally:
        stop_node(process)
