"""Cloud mapping: a map of an unmapped room from a teleoperated tour, change detection
after two passes, how soon robots take an accepted version, and the mapping CPU.

Everything comes from ``--seed``: the building's changes (``robots/agent/sim/changes.py``:
which room is added, which furniture moves, which door closes, where a wall goes up)
and the robots' noise.

- **Mapping** (``cell_agreement``, ``wall_rms_cells``): a simulated robot in the changed
  building is driven by a scripted operator (commands from what it sees, the way a
  person drives with a joystick) from the corridor through the new room's door, around
  the room and back out, at 10 scans/s; its ``odom`` and ``scan`` messages, as the
  robot publishes them, go to the server's mapper (``maps/domain/slam.py``). The map is
  compared with the truth over the room and its walls: the share of cells both call
  known on which they agree, and the RMS distance in cells from each occupied cell of
  the map to the nearest wall of the truth. The mapper starts from the pose the robot
  stands at (a robot localised by a tag knows it within centimetres).
- **CPU** (``cpu_per_robot``): the mapper's thread CPU time over the tour's simulated
  time, as a share of one core: what one robot scanning at 10 Hz costs the server.
- **Change detection** (``change_recall``, ``false_cell_rate``): see ``maps/domain/upkeep.py``
  when present; absent keys are reported as null.
- **Accept to robot** (``accept_to_robot_s``): see ``--robots``.

``--json`` prints one JSON object.
"""

from __future__ import annotations

import argparse
import json
import math
import time
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.ndimage import distance_transform_edt

from maps.domain.demo_building import demo_building
from maps.domain.slam import Mapper, Scan, SlamParams
from robots.agent.sim.body import DiffDriveBody
from robots.agent.sim.changes import (
    ChangeConfig,
    Room,
    changed_demo_world,
    changed_grid,
    plan_changes,
)
from robots.agent.sim.laser import Laser, LaserSpec
from robots.domain.se2 import Pose, wrap

SCAN_RATE = 10.0
SPEED = 0.35  # m/s the operator drives at
TURN = 1.2  # rad/s at most


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--seed", type=int, default=0, help="the world's changes and the noise")
    parser.add_argument("--json", action="store_true", help="print one JSON object")


def run(options: dict[str, Any]) -> None:
    result = measure_mapping(options["seed"])
    if options["json"]:
        print(json.dumps(result))
    else:
        for key, value in result.items():
            print(f"{key:18} {value}")


# --- the tour ----------------------------------------------------------------------------


def tour_waypoints(room: Room) -> list[tuple[float, float]]:
    """From the corridor, 1.2 m before the room's door, through it, around the room 0.8 m
    from its walls, and back out to where it started."""
    x0, y0, x1, y1 = room.door
    door = ((x0 + x1) / 2, (y0 + y1) / 2)
    ix0, iy0, ix1, iy1 = room.interior
    centre = ((ix0 + ix1) / 2, (iy0 + iy1) / 2)
    if (x1 - x0) > (y1 - y0):  # a door through a wall running east-west
        inward = (0.0, math.copysign(1.0, centre[1] - door[1]))
    else:
        inward = (math.copysign(1.0, centre[0] - door[0]), 0.0)
    start = (door[0] - 1.2 * inward[0], door[1] - 1.2 * inward[1])
    inside = (door[0] + 0.9 * inward[0], door[1] + 0.9 * inward[1])
    m = 0.8
    corners = [(ix0 + m, iy0 + m), (ix1 - m, iy0 + m), (ix1 - m, iy1 - m), (ix0 + m, iy1 - m)]
    first = min(range(4), key=lambda i: math.dist(corners[i], inside))
    loop = [corners[(first + k) % 4] for k in range(5)]
    return [start, door, inside, *loop, inside, door, start]


@dataclass
class TourScan:
    odom: Pose
    message: dict[str, Any]
    truth: Pose


def drive_tour(seed: int, room: Room, world: Any) -> list[TourScan]:
    """Drive the tour in ``world``; the scans and odometry poses the robot publishes."""
    points = tour_waypoints(room)
    start = points[0]
    heading = math.atan2(points[1][1] - start[1], points[1][0] - start[0])
    body = DiffDriveBody(world, (start[0], start[1], heading), seed=seed)
    laser = Laser(world, LaserSpec(scan_time=1 / SCAN_RATE), seed=seed + 1)
    out: list[TourScan] = []
    target = 1
    seconds = 0.0
    while target < len(points) and seconds < 600:
        truth = body.pose
        goal = points[target]
        if math.dist(truth[:2], goal) < 0.15:
            target += 1
            continue
        body.command(*_operator(truth, goal))
        body.advance(1 / SCAN_RATE)
        seconds += 1 / SCAN_RATE
        ranges = laser.scan(body.pose)
        message = laser.message(ranges, seconds)
        out.append(TourScan(body.odom_pose, message, body.pose))
    return out


def _operator(pose: Pose, goal: tuple[float, float]) -> tuple[float, float]:
    """Turn toward the goal, then drive at it, as a person with a joystick would."""
    bearing = wrap(math.atan2(goal[1] - pose[1], goal[0] - pose[0]) - pose[2])
    turn = max(-TURN, min(TURN, 2.0 * bearing))
    speed = SPEED if abs(bearing) < 0.35 else 0.0
    return speed, turn


# --- mapping ------------------------------------------------------------------------------


def measure_mapping(seed: int) -> dict[str, Any]:
    changes = plan_changes(seed, ChangeConfig(rooms=1))
    room = changes.rooms[0]
    world = changed_demo_world(changes)
    scans = drive_tour(seed, room, world)
    params = SlamParams()
    mapper = Mapper(params, start=scans[0].truth)
    started = time.thread_time()
    for scan in scans:
        mapper.add(scan.odom, Scan.from_message(scan.message, params.usable_range))
    cpu = time.thread_time() - started
    grid, origin = mapper.grid()
    building = demo_building()
    truth = changed_grid(changes, building)
    agreement, rms = compare_with_truth(grid, origin, truth, building.world_origin, room)
    simulated = len(scans) / SCAN_RATE
    return {
        "seed": seed,
        "room": room.off,
        "tour_s": round(simulated, 1),
        "scans": len(scans),
        "keyframes": mapper.stats.keyframes,
        "loop_closures": mapper.stats.loop_closures,
        "cell_agreement": round(agreement, 4),
        "wall_rms_cells": round(rms, 3),
        "cpu_per_robot": round(cpu / simulated, 4),
        "change_recall": None,
        "false_cell_rate": None,
        "accept_to_robot_s": None,
    }


def compare_with_truth(
    grid: np.ndarray,
    origin: tuple[float, float],
    truth: np.ndarray,
    truth_origin: tuple[float, float],
    room: Room,
    resolution: float = 0.05,
) -> tuple[float, float]:
    """Agreement over the room and its walls on cells both call known, and the RMS
    distance (cells) from the map's occupied cells there to the truth's nearest wall."""
    x0, y0, x1, y1 = room.interior
    margin = 0.3
    cols = np.arange(
        round((x0 - margin - truth_origin[0]) / resolution),
        round((x1 + margin - truth_origin[0]) / resolution),
    )
    rows = np.arange(
        round((y0 - margin - truth_origin[1]) / resolution),
        round((y1 + margin - truth_origin[1]) / resolution),
    )
    rr, cc = np.meshgrid(rows, cols, indexing="ij")
    expected = truth[rr, cc]
    mr = np.round(
        (truth_origin[1] + (rr + 0.5) * resolution - origin[1]) / resolution - 0.5
    ).astype(int)
    mc = np.round(
        (truth_origin[0] + (cc + 0.5) * resolution - origin[0]) / resolution - 0.5
    ).astype(int)
    inside = (mr >= 0) & (mr < grid.shape[0]) & (mc >= 0) & (mc < grid.shape[1])
    built = np.full(expected.shape, -1, np.int8)
    built[inside] = grid[mr[inside], mc[inside]]
    known = (built >= 0) & (expected >= 0)
    agree = (built >= 50) == (expected >= 50)
    agreement = np.count_nonzero(agree & known) / max(1, int(np.count_nonzero(known)))
    walls = distance_transform_edt(expected < 50)
    occupied = built >= 50
    rms = float(np.sqrt(np.mean(walls[occupied] ** 2))) if occupied.any() else math.inf
    return float(agreement), rms
