"""Cloud mapping: a map of an unmapped room from a teleoperated tour, change detection
after two passes, how soon robots take an accepted version, and the mapping CPU.

Everything comes from ``--seed``: the building's changes (``robots/agent/sim/changes.py``:
which room is added, which furniture moves, which door closes, where a wall goes up)
and the robots' noise.

- **Mapping** (``cell_agreement``, ``wall_rms_cells``): a simulated robot in the changed
  building is driven by a scripted operator (commands from what it sees, the way a
  person drives with a joystick) from the corridor through the new room's door, around
  the room and back out, at 10 scans/s; its ``odom`` and ``scan`` messages, as the
  robot publishes them, go to the server's mapper (``maps/domain/slam/mapper.py``). The map is
  compared with the truth over the room and its walls: the share of cells both call
  known on which they agree, and the RMS distance in cells from each occupied cell of
  the map to the nearest wall of the truth. The mapper starts from the pose the robot
  stands at (a robot localised by a tag knows it within centimetres).
- **CPU** (``cpu_per_robot``): the mapper's thread CPU time over the tour's simulated
  time, as a share of one core: what one robot scanning at 10 Hz costs the server.
- **Change detection** (``change_recall``, ``false_cell_rate``): the building with the
  seed's moved and new furniture, closed door and new wall; scans are taken along a loop
  through every changed room or atrium, 1 m inside its walls, every 8 cm (a robot at
  0.4 m/s scanning at 5 Hz), twice (two passes, other laser noise), at pose estimates
  with 3 cm and 0.6 degree Gaussian error, into ``maps/domain/upkeep.py``'s evidence on
  the stored map. ``change_recall`` is the share of the changed cells a laser could see
  on both passes (a return ended in a new obstacle's cell; a beam crossed a vanished
  one's: cells inside a new obstacle are seen by nobody) that were proposed;
  ``false_cell_rate`` the proposed cells that did not change, over the cells observed
  (``false_share_of_proposed``: over the cells proposed).
- **No change, live** (``false_proposed_cells``, ``no_change_*``): where upkeep failed
  before. A daphne on a scratch database seeded with the demo building (its maps are the
  building as it is: nothing changed), three simulated robots in this process starting
  by the entrance tag with their cameras, particle filters and rosbridge as ``make demo``
  runs them, each sent from sub-map to sub-map (``TOUR``) again and again, while a second
  process keeps a core busy (``--no-load`` leaves it out), for ``--no-change-minutes``
  simulated minutes of each robot (30 by default; the robots' clocks fall behind the
  wall clock on a loaded machine, as they did when it failed). Every cell the fleet then
  proposes is a false one: ``false_proposed_cells`` must be 0.
  ``no_change_simulated_min`` is how far the robots' clocks got, ``no_change_wall_min``
  the wall time it took.
- **Accept to robot** (``accept_to_robot_s``): a daphne on a scratch database seeded
  with the demo building and ``--robots`` simulated robots in this process, standing in
  Corridor A (localised from the entrance tag); an admin's accepted change (a new
  version, over HTTP) until every robot holds it (their conditional requests every
  ``1 / map_check_rate`` = 2 s).

``--json`` prints one JSON object.
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import itertools
import json
import math
import sys
import time
from dataclasses import dataclass
from typing import Any

import httpx
import numpy as np
from scipy.ndimage import distance_transform_edt

from cloudnav_core.grid import OCCUPIED_AT
from cloudnav_core.params import RobotConfig
from cloudnav_core.se2 import Pose, wrap
from maps.domain.demo_building import demo_building, space_interiors
from maps.domain.slam.mapper import Mapper
from maps.domain.slam.params import SlamParams
from maps.domain.slam.scans import Scan
from maps.domain.upkeep import Evidence
from maps.domain.versions import cell_classes
from robots.agent.fleet import FleetOptions, build_fleet, place_at_truth, run_fleet
from robots.agent.sim.body import DiffDriveBody
from robots.agent.sim.changes import (
    ChangeConfig,
    Room,
    WorldChanges,
    changed_demo_world,
    changed_grid,
    plan_changes,
)
from robots.agent.sim.laser import Laser, LaserSpec

SCAN_RATE = 10.0
HTTP_TIMEOUT = 60.0  # seconds: the bench's server answers slowly on a loaded machine
SPEED = 0.35  # m/s the operator drives at
TURN = 1.2  # rad/s at most


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--seed", type=int, default=0, help="the world's changes and the noise")
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    parser.add_argument("--robots", type=int, default=3, help="robots taking a new version")
    parser.add_argument(
        "--no-change-minutes",
        type=float,
        default=30.0,
        help="simulated minutes of each robot in the no-change live run (0: no such run)",
    )
    parser.add_argument(
        "--no-change-time-scale",
        type=float,
        default=1.0,
        help="the robots' pace against the wall clock in the no-change run",
    )
    parser.add_argument(
        "--no-load", action="store_true", help="no second process loading the machine"
    )


def run(options: dict[str, Any]) -> None:
    result = measure_mapping(options["seed"])
    result.update(measure_change_detection(options["seed"]))
    result["accept_to_robot_s"] = asyncio.run(measure_accept_to_robot(options))
    if options["no_change_minutes"] > 0:
        result.update(asyncio.run(measure_no_change(options)))
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
    grid, origin = mapper.grid()
    cpu = time.thread_time() - started
    building = demo_building()
    truth = changed_grid(changes, building)
    agreement, rms = compare_with_truth(grid, origin, truth, building.world_origin, room.interior)
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
    }


def compare_with_truth(
    grid: np.ndarray,
    origin: tuple[float, float],
    truth: np.ndarray,
    truth_origin: tuple[float, float],
    area: tuple[float, float, float, float],
    resolution: float = 0.05,
) -> tuple[float, float]:
    """Agreement over ``area`` (a room's interior, x0, y0, x1, y1) and its walls on cells
    both call known, and the RMS distance (cells) from the map's occupied cells there to
    the truth's nearest wall."""
    x0, y0, x1, y1 = area
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
    agree = (built >= OCCUPIED_AT) == (expected >= OCCUPIED_AT)
    agreement = np.count_nonzero(agree & known) / max(1, int(np.count_nonzero(known)))
    walls = distance_transform_edt(expected < OCCUPIED_AT)
    occupied = built >= OCCUPIED_AT
    rms = float(np.sqrt(np.mean(walls[occupied] ** 2))) if occupied.any() else math.inf
    return float(agreement), rms


# --- change detection ---------------------------------------------------------------------

POSE_SIGMA = (0.03, 0.03, math.radians(0.6))
STEP = 0.08  # metres between scans: 0.4 m/s at 5 scans/s


def measure_change_detection(seed: int) -> dict[str, Any]:
    changes = plan_changes(seed, ChangeConfig(rooms=0))
    building = demo_building()
    world = changed_demo_world(changes)
    truth = cell_classes(changed_grid(changes, building))
    stored = cell_classes(building.world)
    evidence = Evidence(building.world, building.world_origin, building.resolution)
    rng = np.random.default_rng(seed)
    seen_hit = np.zeros(truth.shape, np.uint8)
    seen_crossed = np.zeros(truth.shape, np.uint8)
    for index in range(2):
        hit, crossed = _pass(world, changes, evidence, rng, seed + index, inset=1.0 + 0.2 * index)
        seen_hit += hit
        seen_crossed += crossed
        evidence.end_pass()
    proposal = evidence.proposal()
    detected = np.zeros(truth.shape, bool)
    for cells in (proposal.added, proposal.removed):
        detected[cells[:, 0], cells[:, 1]] = True
    added = (truth == 1) & (stored != 1)
    removed = (truth == 0) & (stored == 1)
    visible = (added & (seen_hit == 2)) | (removed & (seen_crossed == 2))
    false = detected & ~(added | removed)
    found = int(np.count_nonzero(detected & visible))
    return {
        "changes": list(changes.notes),
        "changed_cells": int(np.count_nonzero(added | removed)),
        "changed_cells_visible": int(np.count_nonzero(visible)),
        "proposed_added": len(proposal.added),
        "proposed_removed": len(proposal.removed),
        "change_recall": round(found / max(1, int(np.count_nonzero(visible))), 4),
        "false_cell_rate": round(
            int(np.count_nonzero(false)) / max(1, int(evidence.observed.sum())), 5
        ),
        "false_share_of_proposed": round(
            int(np.count_nonzero(false)) / max(1, int(detected.sum())), 4
        ),
        "untrusted_scans": evidence.untrusted,
        "misaligned_scans": evidence.misaligned,
        "false_added": int(np.count_nonzero(false & (stored != 1))),
    }


def _pass(
    world: Any,
    changes: WorldChanges,
    evidence: Evidence,
    rng: np.random.Generator,
    seed: int,
    inset: float,
) -> tuple[np.ndarray, np.ndarray]:
    """One pass through every changed space; the cells truth returns ended in and beams
    crossed (for what could be seen)."""
    laser = Laser(world, LaserSpec(), seed=seed)
    angles = laser.spec.angles()
    every = max(1, len(angles) // evidence.params.beams)
    shape = evidence.stored.shape
    hit = np.zeros(shape, np.uint8)
    crossed = np.zeros(shape, np.uint8)
    for pose in _loops(changed_spaces(changes), inset):
        if not world.disc_is_free(pose[0], pose[1], 0.2):
            continue
        ranges = laser.scan(pose).astype(np.float64)
        ranges[~np.isfinite(ranges)] = np.nan
        noisy = tuple(v + rng.normal(0.0, s) for v, s in zip(pose, POSE_SIGMA, strict=True))
        evidence.add(noisy, Scan(angles, ranges))  # type: ignore[arg-type]
        used = angles[::every] + pose[2]
        exact = world.cast(pose[0], pose[1], used, evidence.params.max_range)
        _mark(evidence, pose, exact.distance, used, hit, crossed)
    return hit.clip(0, 1), crossed.clip(0, 1)


def _mark(
    evidence: Evidence,
    pose: Pose,
    distance: np.ndarray,
    angles: np.ndarray,
    hit: np.ndarray,
    crossed: np.ndarray,
) -> None:
    good = np.isfinite(distance)
    ends = np.column_stack(
        (
            pose[0] + distance[good] * np.cos(angles[good]),
            pose[1] + distance[good] * np.sin(angles[good]),
        )
    )
    cells = evidence._cells(ends)
    cells = cells[cells[:, 0] >= 0]
    hit[cells[:, 0], cells[:, 1]] = 1
    through, _frees = evidence._crossed(pose, distance[good], angles[good])
    crossed[through[:, 0], through[:, 1]] = 1


def changed_spaces(changes: WorldChanges) -> list[tuple[float, float, float, float]]:
    """The main interiors of the rooms and atria holding a change (both sides of a
    closed door)."""
    spaces = []
    for interiors in space_interiors().values():
        main = interiors[0]
        grown = (main[0] - 0.3, main[1] - 0.3, main[2] + 0.3, main[3] + 0.3)
        if any(
            _overlaps(grown, rect) for rect in (*changes.emptied, *changes.filled, *changes.walls)
        ):
            spaces.append(main)
    return spaces


def _overlaps(a: tuple[float, ...], b: tuple[float, ...]) -> bool:
    return a[0] < b[2] and b[0] < a[2] and a[1] < b[3] and b[1] < a[3]


def _loops(spaces: list[tuple[float, float, float, float]], inset: float) -> list[Pose]:
    """Poses every ``STEP`` along a loop ``inset`` inside each space (its centre line
    for a narrow one), heading along it."""
    poses: list[Pose] = []
    for x0, y0, x1, y1 in spaces:
        m = min(inset, (x1 - x0) / 2 - 0.3, (y1 - y0) / 2 - 0.3)
        corners = [
            (x0 + m, y0 + m),
            (x1 - m, y0 + m),
            (x1 - m, y1 - m),
            (x0 + m, y1 - m),
            (x0 + m, y0 + m),
        ]
        for (ax, ay), (bx, by) in itertools.pairwise(corners):
            length = math.hypot(bx - ax, by - ay)
            heading = math.atan2(by - ay, bx - ax)
            for k in range(max(1, int(length / STEP))):
                t = k * STEP / max(length, 1e-9)
                poses.append((ax + t * (bx - ax), ay + t * (by - ay), heading))
    return poses


# --- accept to robot ------------------------------------------------------------------------


async def measure_accept_to_robot(options: dict[str, Any]) -> float:
    """Seconds from an admin's accepted change until every robot holds the new version."""
    from benchmarks.agent import demo_server

    robots = options["robots"]
    with demo_server({"url": None, "robots": robots}) as (url, tokens):
        # No camera: the robots are placed in Corridor A by an initial pose, so the
        # simulation keeps its pace on a busy machine.
        config = RobotConfig(camera_rate=0, detect_rate=0)
        fleet = build_fleet(
            list(tokens.items())[:robots], FleetOptions(url, particles=0, robot=config)
        )
        running = asyncio.create_task(run_fleet(fleet, 1.0))
        try:
            await place_at_truth(fleet, ["boccioni_1/CorridorA"] * len(fleet))
            await _until(lambda: all(_holds(m, 1) for m in fleet), 60)
            async with httpx.AsyncClient(
                base_url=url, auth=("admin", admin_password()), timeout=HTTP_TIMEOUT
            ) as http:
                accepted = time.monotonic()
                answer = await http.post(
                    "/api/buildings/boccioni_1/maps/CorridorA/versions/1/rollback",
                    json={"note": "benchmark: an accepted change"},
                )
                answer.raise_for_status()
            await _until(lambda: all(_holds(m, 2) for m in fleet), 60)
            return round(time.monotonic() - accepted, 2)
        finally:
            running.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await running


# --- no change, live --------------------------------------------------------------------

TOUR = ("Atrium1", "CorridorB", "CorridorC", "Atrium2", "CorridorD", "Atrium3", "Office7")
"""Where the robots are sent in turn (the centre of each sub-map's main space), and back."""


async def measure_no_change(options: dict[str, Any]) -> dict[str, Any]:
    """Three robots touring the unchanged demo building; what the fleet proposed."""
    from benchmarks.agent import demo_server

    minutes = options["no_change_minutes"]
    load = None if options["no_load"] else _busy_process()
    try:
        with demo_server({"url": None, "robots": 3}) as (url, tokens):
            fleet = build_fleet(list(tokens.items())[:3], FleetOptions(url, seed=options["seed"]))
            started = time.monotonic()
            running = asyncio.create_task(run_fleet(fleet, options["no_change_time_scale"]))
            tracks: list[tuple[str, float, Any, Any]] = []
            watching = asyncio.create_task(_watch(fleet, tracks))
            try:
                await _tour_until(fleet, minutes * 60, options["seed"])
                watching.cancel()
                simulated = min(m.robot.seconds for m in fleet)
                await asyncio.sleep(2 * 5.0 + 2.0)  # the upkeep's last batch and save
            finally:
                running.cancel()
                with contextlib.suppress(asyncio.CancelledError):
                    await running
            proposed = await _open_proposals(url)
            details = await _false_cells(url, tracks)
    finally:
        if load is not None:
            load.kill()
            load.wait()
    return {
        "false_proposed_cells": sum(proposed.values()),
        "no_change_proposals": proposed,
        "no_change_simulated_min": round(simulated / 60, 2),
        "no_change_wall_min": round((time.monotonic() - started) / 60, 2),
        "no_change_loaded": load is not None,
        "no_change_cells": details,
    }


async def _watch(fleet: list[Any], tracks: list[tuple[str, float, Any, Any]]) -> None:
    """Every robot's true pose and its estimate (sub-map, pose), five times a wall second."""
    while True:
        for member in fleet:
            robot = member.robot
            current = robot.supervisor.current
            code = current.code if current is not None else ""
            tracks.append(
                (member.name, robot.seconds, robot.hardware.true_pose, (code, robot.tracker.pose()))
            )
        await asyncio.sleep(0.2)


async def _false_cells(url: str, tracks: list[tuple[str, float, Any, Any]]) -> list[dict[str, Any]]:
    """Each proposed cell of the no-change run: where it is, and what stood on it or near
    it (a robot's body, by the truth) and how far off the robots' estimates were then."""
    async with httpx.AsyncClient(
        base_url=url, auth=("admin", admin_password()), timeout=HTTP_TIMEOUT
    ) as http:
        maps = {m["code"]: m for m in (await http.get("/api/buildings/boccioni_1/maps/")).json()}
        found = []
        for code, entry in maps.items():
            answer = await http.get(f"/api/buildings/boccioni_1/maps/{code}/changes/?state=open")
            for proposal in answer.json():
                for kind in ("added", "removed"):
                    for index, (row, col) in enumerate(proposal[kind]):
                        found.append(
                            _cell_story(code, entry, kind, row, col, proposal, index, tracks)
                        )
        return found


def _cell_story(
    code: str,
    entry: dict[str, Any],
    kind: str,
    row: int,
    col: int,
    proposal: dict[str, Any],
    index: int,
    tracks: list[tuple[str, float, Any, Any]],
) -> dict[str, Any]:
    res = entry["resolution"]
    ox, oy = entry["origin"][:2]
    x, y = ox + (col + 0.5) * res, oy + (row + 0.5) * res
    near = [
        (name, round(t, 1), round(math.hypot(p[0] - x, p[1] - y), 2))
        for name, t, p, _ in tracks
        if math.hypot(p[0] - x, p[1] - y) < 0.45
    ]
    errors = [
        math.hypot(p[0] - e[1][0], p[1] - e[1][1])
        for _, _, p, e in tracks
        if e[0] == code and math.hypot(p[0] - x, p[1] - y) < 6.0
    ]
    big = sorted(errors)[-5:]
    return {
        "map": code,
        "kind": kind,
        "cell": [row, col],
        "xy": [round(x, 3), round(y, 3)],
        "passes": proposal[f"{kind}_passes"][index],
        "robots": proposal[f"{kind}_robots"][index],
        "robot_bodies_within_045m": len(near),
        "first_near": near[:3],
        "last_near": near[-3:],
        "est_error_max_within_6m": [round(v, 3) for v in big],
    }


def _busy_process() -> Any:
    """A second process keeping a core busy, as the machine was when upkeep failed."""
    import subprocess

    return subprocess.Popen([sys.executable, "-c", "while True: pass"])


async def _tour_until(fleet: list[Any], seconds: float, seed: int) -> None:
    """Send each idle robot to its next sub-map of ``TOUR`` until every robot's clock
    has run ``seconds`` (no wall deadline: a loaded machine only takes longer)."""
    spaces = space_interiors()
    steps = [seed + index for index in range(len(fleet))]
    said = time.monotonic()
    while min(m.robot.seconds for m in fleet) < seconds:
        if time.monotonic() - said >= 60:  # a long run says how far it got
            said = time.monotonic()
            clocks = ", ".join(f"{m.robot.seconds:.0f}" for m in fleet)
            print(f"no change: robots' clocks at {clocks} of {seconds:.0f} s", file=sys.stderr)
        for index, member in enumerate(fleet):
            robot = member.robot
            if robot.navigator.board.active is None and robot.supervisor.current is not None:
                code = TOUR[steps[index] % len(TOUR)]
                steps[index] += 1
                x0, y0, x1, y1 = spaces[code][0]
                robot.on_goal(
                    {
                        "header": {"frame_id": f"boccioni_1/{code}"},
                        "pose": {
                            "position": {"x": (x0 + x1) / 2, "y": (y0 + y1) / 2, "z": 0.0},
                            "orientation": {"w": 1.0},
                        },
                    }
                )
        await asyncio.sleep(1.0)


async def _open_proposals(url: str) -> dict[str, int]:
    """Cells of each sub-map's open proposal (by code; sub-maps with none left out)."""
    async with httpx.AsyncClient(
        base_url=url, auth=("admin", admin_password()), timeout=HTTP_TIMEOUT
    ) as http:
        maps = (await http.get("/api/buildings/boccioni_1/maps/")).json()
        found: dict[str, int] = {}
        for entry in maps:
            code = entry["code"]
            answer = await http.get(f"/api/buildings/boccioni_1/maps/{code}/changes/?state=open")
            cells = sum(len(p["added"]) + len(p["removed"]) for p in answer.json())
            if cells:
                found[code] = cells
        return found


def _holds(member: Any, revision: int) -> bool:
    current = member.robot.supervisor.current
    return current is not None and current.code == "CorridorA" and current.revision == revision


def admin_password() -> str:
    import os

    return os.environ.get("CLOUDNAV_DEMO_PASSWORD", "admin-demo")


async def _until(check: Any, seconds: float) -> None:
    deadline = time.monotonic() + seconds
    while not check():
        if time.monotonic() > deadline:
            raise RuntimeError("the robots never got there")
        await asyncio.sleep(0.05)
