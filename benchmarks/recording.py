"""Recording cost: 100 robots at the default set, bytes per robot-hour, seek and export.

Part one feeds the recorder's tap (``Recorder.offered``, what the topic bus calls) in real
time with ``--robots`` robots at the default set: pose, odom and scan (360 beams) at 10 Hz,
nav_status at 1 Hz, plan every 10 s, map_id once, cmd_vel at 10 Hz for one robot in ten
(the teleoperated ones). The same paced loop runs once with no recorder and once with
one writing real files; the difference of the process's CPU time (writer thread
included) over the wall time is the recording's extra CPU, in cores. It reports the drops
(the queues' counters) and the bytes written per robot-hour.

Wall times on a shared, loaded machine overstate what one request costs, so the CPU time
of the process is reported beside each.

Part two writes a one-hour file of one robot at that rate (in simulated time), then times
``--seeks`` seeks to seeded random points (open the file, read the first message at or
after the point) and the export of the whole hour as one MCAP file, read to the end.

Run ``python manage.py bench recording --seed N --json``.
"""

from __future__ import annotations

import argparse
import json
import math
import random
import statistics
import tempfile
import time
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

from telemetry.domain import ros1
from telemetry.domain.bus import Topic
from telemetry.recording import export, files
from telemetry.recording.plans import DEFAULT
from telemetry.recording.recorder import Recorder, RecorderConfig

NS = 1_000_000_000
TICK = 0.1  # seconds: the 10 Hz topics publish once per tick


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--seed", type=int, default=1, help="seed of the messages and seeks")
    parser.add_argument("--robots", type=int, default=100, help="robots recorded at once")
    parser.add_argument("--seconds", type=float, default=20.0, help="real time of each run")
    parser.add_argument("--seeks", type=int, default=20, help="seeks in the one-hour file")
    parser.add_argument("--json", action="store_true", help="print one JSON object")


def run(options: argparse.Namespace | Mapping[str, Any]) -> None:
    opts = argparse.Namespace(**options) if isinstance(options, Mapping) else options
    rng = random.Random(opts.seed)
    with tempfile.TemporaryDirectory(prefix="cloudnav-bench-recording-") as scratch:
        root = Path(scratch)
        live = _live(root / "live", opts.robots, opts.seconds, rng)
        hour = _hour(root / "hour", opts.seeks, rng)
    result = {"benchmark": "recording", "seed": opts.seed, **live, **hour}
    if opts.json:
        print(json.dumps(result))
    else:
        for key, value in result.items():
            print(f"{key}: {value}")


# ---------------------------------------------------------------- messages


def _stamp(t: float) -> dict[str, int]:
    return {"sec": int(t), "nanosec": int((t % 1) * 1e9)}


def _pose(t: float, rng: random.Random) -> dict[str, Any]:
    yaw = rng.uniform(-math.pi, math.pi)
    return {
        "header": {"stamp": _stamp(t), "frame_id": "boccioni_1/CorridorA"},
        "pose": {
            "position": {"x": rng.uniform(0, 40), "y": rng.uniform(0, 20), "z": 0.0},
            "orientation": {"x": 0.0, "y": 0.0, "z": math.sin(yaw / 2), "w": math.cos(yaw / 2)},
        },
    }


def _odom(t: float, rng: random.Random) -> dict[str, Any]:
    pose = _pose(t, rng)
    return {
        "header": {"stamp": _stamp(t), "frame_id": "odom"},
        "child_frame_id": "base_link",
        "pose": {"pose": pose["pose"], "covariance": [rng.random() * 0.01 for _ in range(36)]},
        "twist": {
            "twist": {
                "linear": {"x": rng.uniform(0, 0.5), "y": 0.0, "z": 0.0},
                "angular": {"x": 0.0, "y": 0.0, "z": rng.uniform(-1, 1)},
            },
            "covariance": [rng.random() * 0.01 for _ in range(36)],
        },
    }


def _scan(t: float, rng: random.Random) -> dict[str, Any]:
    ranges = [None if rng.random() < 0.1 else round(rng.uniform(0.2, 8.0), 3) for _ in range(360)]
    return {
        "header": {"stamp": _stamp(t), "frame_id": "laser"},
        "angle_min": -math.pi,
        "angle_max": math.pi,
        "angle_increment": 2 * math.pi / 360,
        "time_increment": 0.0,
        "scan_time": 0.1,
        "range_min": 0.12,
        "range_max": 8.0,
        "ranges": ranges,
        "intensities": [],
    }


def _plan(t: float, rng: random.Random) -> dict[str, Any]:
    poses = [_pose(t, rng) for _ in range(60)]
    return {"header": {"stamp": _stamp(t), "frame_id": "boccioni_1/CorridorA"}, "poses": poses}


def _status(t: float, rng: random.Random) -> dict[str, Any]:
    goal = {"stamp": _stamp(t), "id": f"goal-{rng.randrange(1000)}"}
    return {
        "header": {"stamp": _stamp(t), "frame_id": ""},
        "status_list": [{"goal_id": goal, "status": 1, "text": "active"}],
    }


def _twist(_t: float, rng: random.Random) -> dict[str, Any]:
    return {
        "linear": {"x": rng.uniform(0, 0.5), "y": 0.0, "z": 0.0},
        "angular": {"x": 0.0, "y": 0.0, "z": rng.uniform(-1, 1)},
    }


Builder = Callable[[float, random.Random], dict[str, Any]]
BUILDERS: dict[str, Builder] = {
    "pose": _pose,
    "odom": _odom,
    "scan": _scan,
    "plan": _plan,
    "nav_status": _status,
    "cmd_vel": _twist,
    "map_id": lambda _t, _rng: {"data": "boccioni_1/CorridorA"},
}
TYPES = {
    "pose": "geometry_msgs/PoseStamped",
    "odom": "nav_msgs/Odometry",
    "scan": "sensor_msgs/LaserScan",
    "plan": "nav_msgs/Path",
    "nav_status": "actionlib_msgs/GoalStatusArray",
    "cmd_vel": "geometry_msgs/Twist",
    "map_id": "std_msgs/String",
}


def _due(tick: int, robot: int) -> list[str]:
    """The topics robot number ``robot`` publishes at tick ``tick`` (ticks of 0.1 s)."""
    due = ["pose", "odom", "scan"]
    if robot % 10 == 0:
        due.append("cmd_vel")
    if tick % 10 == robot % 10:
        due.append("nav_status")
    if tick % 100 == robot % 100:
        due.append("plan")
    if tick == 0:
        due.append("map_id")
    return due


# ---------------------------------------------------------------- part one


def _pool(rng: random.Random) -> dict[str, list[dict[str, Any]]]:
    """A few messages of each topic, made before the clock runs."""
    return {k: [make(1.8e9 + i, rng) for i in range(8)] for k, make in BUILDERS.items()}


def _feed(recorder: Recorder | None, robots: int, seconds: float, rng: random.Random) -> float:
    """Offer the robots' messages in real time for ``seconds``; return CPU seconds used."""
    pool = _pool(rng)
    topics = {(r, k): Topic(f"/robot{r}/{k}", TYPES[k]) for r in range(robots) for k in BUILDERS}
    if recorder is not None:
        for r in range(robots):
            recorder.connected(f"robot{r}")
    started, cpu = time.monotonic(), time.process_time()
    tick = 0
    while (now := time.monotonic()) < started + seconds:
        for r in range(robots):
            for kind in _due(tick, r):
                if recorder is not None:
                    recorder.offered(topics[r, kind], pool[kind][tick % 8])
        tick += 1
        time.sleep(max(0.0, started + tick * TICK - now))
    if recorder is not None:
        recorder.stop(timeout=120)
    return time.process_time() - cpu


def _live(root: Path, robots: int, seconds: float, rng: random.Random) -> dict[str, Any]:
    baseline = _feed(None, robots, seconds, rng)
    config = RecorderConfig(root=root, file_seconds=3600)
    recorder = Recorder(config, lambda robots: dict.fromkeys(robots, DEFAULT), lambda: [])
    recorder.start()
    recording = _feed(recorder, robots, seconds, rng)
    written = sum(e.written for e in recorder.robots.values())
    dropped = sum(e.dropped for e in recorder.robots.values())
    size = sum(f.size for r in range(robots) for f in files.files_of(root, f"robot{r}"))
    return {
        "robots": robots,
        "seconds": seconds,
        "messages_per_second": round(written / seconds),
        "extra_cpu_cores": round((recording - baseline) / seconds, 4),
        "dropped": dropped,
        "failed": sum(e.failed for e in recorder.robots.values()),
        "bytes_per_robot_hour": round(size / robots / seconds * 3600),
    }


# ---------------------------------------------------------------- part two


def _hour(root: Path, seeks: int, rng: random.Random) -> dict[str, Any]:
    pool = _pool(rng)
    start = 1_800_000_000
    started = time.perf_counter()
    writer = files.RotatingFiles(root, "r1", max_seconds=7200, max_bytes=2**40)
    for tick in range(36000):
        t = start + tick * TICK
        for kind in _due(tick, 1):
            data = ros1.encode(TYPES[kind], pool[kind][tick % 8])
            schema = ros1.schema_text(TYPES[kind]).encode()
            writer.write(files.Record(f"/r1/{kind}", TYPES[kind], schema, int(t * NS), data))
    writer.close()
    write_seconds = time.perf_counter() - started
    [hour] = files.files_of(root, "r1")
    seek_times, seek_cpu = [], []
    for _ in range(seeks):
        point = int((start + rng.uniform(0, 3600)) * NS)
        began, cpu = time.perf_counter(), time.process_time()
        first = next(files.open_messages(hour.path, point, 2**63 - 1))
        seek_times.append(time.perf_counter() - began)
        seek_cpu.append(time.process_time() - cpu)
        assert first.log_time >= point
    began, cpu = time.perf_counter(), time.process_time()
    exported = 0
    for piece in export.mcap_stream(export.records(root, ["r1"], start * NS, (start + 3600) * NS)):
        exported += len(piece)
    export_seconds = time.perf_counter() - began
    export_cpu = time.process_time() - cpu
    return {
        "hour_file_bytes": hour.size,
        "hour_file_write_seconds": round(write_seconds, 2),
        "seek_seconds_max": round(max(seek_times), 4),
        "seek_seconds_median": round(statistics.median(seek_times), 4),
        "seek_cpu_seconds_max": round(max(seek_cpu), 4),
        "export_hour_seconds": round(export_seconds, 2),
        "export_hour_cpu_seconds": round(export_cpu, 2),
        "export_hour_bytes": exported,
    }
