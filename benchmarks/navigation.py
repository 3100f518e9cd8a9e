"""Navigation among people and robots: DWA or TEB over seeded trials in the demo building.

Scenarios, each run ``--trials`` times with seeds drawn from ``--seed``:

- ``corridor_0``, ``corridor_3``, ``corridor_8``: along Corridor A (14 m by 2.4 m), with
  0, 3 or 8 people walking seeded routes in it (crossing, pausing, some walking
  towards the robot; none starts within 1 m of the robot's start);
- ``atrium_0``, ``atrium_3``, ``atrium_8``: across Atrium 1 (8 m square, pillars and a
  table) corner to corner, with 0, 3 or 8 people;
- ``crossing``: a person walking back and forth across Atrium 1, across the robot's way;
- ``head_on``: two robots sent to each other's start along Corridor A;
- ``overtaking``: a slow person (0.25 m/s, slower than any walker of the crowds: someone
  pushing a trolley) walking ahead of the robot along Corridor A.

Robots run the agent's own ``Driver`` (global A* on the building's grid, then the local
planner chosen by ``--planner``) on the simulated body and laser at 10 Hz; the driver is
given the true pose (this measures local planning, not localisation). A trial succeeds
when every robot arrives within ``TIME_LIMIT`` simulated seconds. A collision is a
contact: a robot's footprint touching a person or another robot, or its bumper stopping
it at a wall. ``min_clearance_m`` is the smallest gap seen between a robot's footprint
and a person or another robot; ``cycle_*_ms`` the process's CPU time (BLAS threads
included) of each control cycle of the driver, global replanning included.

``python manage.py bench navigation --seed 1 --planner teb --json`` prints one JSON
object; without ``--json``, a table.
"""

from __future__ import annotations

import argparse
import json
import math
import statistics
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from cloudnav_core.params import RobotConfig
from cloudnav_core.se2 import Pose
from maps.domain.demo_building import demo_building
from maps.domain.planning import warm_up
from robots.agent.depth_scan import ObstacleMemory, seen_obstacles
from robots.agent.navigation.clearance import LocalObstacles
from robots.agent.navigation.commands import STOP
from robots.agent.navigation.driver import Driver
from robots.agent.navigation.legs import DriveState
from robots.agent.sim.crowd import Body, Crowd, Person, seeded_people
from robots.agent.sim.hardware import SimHardware
from robots.agent.sim.world import World, demo_world
from robots.agent.supervisor.submaps import SubMap

TIME_LIMIT = 90.0
"""Simulated seconds a trial may take."""
CONTACT = 0.005
"""Metres: a gap this small between footprints is a contact."""
CORRIDOR = (3.8, 22.0, 17.8, 24.4)
"""Corridor A's interior, x0, y0, x1, y1."""
ATRIUM = (18.0, 19.2, 26.0, 27.2)
"""Atrium 1's interior."""
WEST, EAST = (5.0, 23.2, 0.0), (16.6, 23.2, 0.0)
"""The corridor trials' ends."""
SOUTH_WEST, NORTH_EAST = (18.7, 19.9, math.pi / 4), (25.3, 26.5, math.pi / 4)
"""The atrium trials' corners."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--seed", type=int, default=1, help="seed of the trials")
    parser.add_argument("--planner", choices=("dwa", "teb"), default="teb")
    parser.add_argument(
        "--sensors", choices=("laser", "rgbd"), default="laser",
        help="the robots' laser, or an RGB-D camera alone (scan made from depth)",
    )  # fmt: skip
    parser.add_argument("--trials", type=int, default=3, help="trials per scenario")
    parser.add_argument("--scenarios", help="comma-separated subset of the scenarios")
    parser.add_argument("--json", action="store_true", help="print one JSON object")


def run(options: dict[str, Any]) -> None:
    warm_up()
    names = options["scenarios"].split(",") if options.get("scenarios") else list(SCENARIOS)
    config = RobotConfig(local_planner=options["planner"], sensors=options.get("sensors", "laser"))
    results = [
        trial(name, config, options["seed"] * 1000 + 10 * index + number)
        for index, name in enumerate(names)
        for number in range(options["trials"])
    ]
    summary = summarise(results, options)
    print(json.dumps(summary) if options["json"] else table(summary))


# --- scenarios -------------------------------------------------------------------------


@dataclass(frozen=True)
class Setup:
    """Robots' starts and goals, and the people."""

    robots: list[tuple[Pose, Pose]]
    people: list[Person]


def _crowd_in(
    area: tuple[float, float, float, float], count: int, start: Pose
) -> Callable[[World, int], list[Person]]:
    """``count`` people walking in ``area``, none starting near the robot's ``start``."""

    def people(world: World, seed: int) -> list[Person]:
        if not count:
            return []
        return seeded_people(world, count, seed, _mask(world, area), [start[:2]])

    return people


def _mask(world: World, area: tuple[float, float, float, float]) -> np.ndarray:
    rows, cols = np.indices(world.cells.shape)
    x = world.origin[0] + (cols + 0.5) * world.resolution
    y = world.origin[1] + (rows + 0.5) * world.resolution
    x0, y0, x1, y1 = area
    return np.asarray((x > x0) & (x < x1) & (y > y0) & (y < y1))


def _corridor(count: int) -> Callable[[World, int], Setup]:
    people = _crowd_in(CORRIDOR, count, WEST)
    return lambda world, seed: Setup([(WEST, EAST)], people(world, seed))


def _atrium(count: int) -> Callable[[World, int], Setup]:
    people = _crowd_in(ATRIUM, count, SOUTH_WEST)
    return lambda world, seed: Setup([(SOUTH_WEST, NORTH_EAST)], people(world, seed))


def _crossing(_world: World, _seed: int) -> Setup:
    across = Person([(22.0, 23.9), (22.0, 26.95)], speed=0.8, start_after=2.0)
    return Setup([((18.7, 26.3, 0.0), (25.3, 26.3, 0.0))], [across])


def _head_on(_world: World, _seed: int) -> Setup:
    back = (EAST[0], EAST[1], math.pi)
    return Setup([(WEST, EAST), (back, (WEST[0], WEST[1], math.pi))], [])


def _overtaking(_world: World, _seed: int) -> Setup:
    slow = Person([(6.4, 23.2), (17.3, 23.2)], speed=0.25)
    return Setup([(WEST, EAST)], [slow])


SCENARIOS: dict[str, Callable[[World, int], Setup]] = {
    "corridor_0": _corridor(0),
    "corridor_3": _corridor(3),
    "corridor_8": _corridor(8),
    "atrium_0": _atrium(0),
    "atrium_3": _atrium(3),
    "atrium_8": _atrium(8),
    "crossing": _crossing,
    "head_on": _head_on,
    "overtaking": _overtaking,
}


# --- one trial -------------------------------------------------------------------------


@dataclass
class RobotRun:
    """One robot of a trial: its hardware, driver, goal, and what was measured."""

    hardware: SimHardware
    driver: Driver
    goal: Pose
    seen: ObstacleMemory
    arrived_at: float | None = None
    failed: str = ""
    contacts: int = 0
    touching: bool = False
    min_clearance: float = math.inf
    length: float = 0.0
    turning: float = 0.0
    cycles_ms: list[float] = field(default_factory=list)


@dataclass(frozen=True)
class TrialResult:
    scenario: str
    success: bool
    collisions: int
    min_clearance: float
    time: float | None
    length: float
    smoothness: float
    cycles_ms: list[float]


def trial(scenario: str, config: RobotConfig, seed: int) -> TrialResult:
    """Run ``scenario`` once with ``seed`` and measure it."""
    world = demo_world()
    setup = SCENARIOS[scenario](world, seed)
    crowd = Crowd(world, setup.people)
    submap = building_submap()
    runs = [
        _robot_run(world, crowd, config, seed + i, start, goal)
        for i, (start, goal) in enumerate(setup.robots)
    ]
    seconds = 0.0
    while seconds < TIME_LIMIT and any(r.arrived_at is None and not r.failed for r in runs):
        seconds += config.period
        for run in runs:
            _step(run, submap, seconds, crowd)
    return _result(scenario, runs)


def _robot_run(
    world: World, crowd: Crowd, config: RobotConfig, seed: int, start: Pose, goal: Pose
) -> RobotRun:
    hardware = SimHardware(
        world, start, seed=seed, limits=config.body, crowd=crowd, sensors=config.sensors
    )
    return RobotRun(hardware, Driver(config), goal, seen_obstacles(hardware.scan_mount, config))


def _step(run: RobotRun, submap: SubMap, seconds: float, crowd: Crowd) -> None:
    hardware = run.hardware
    before = hardware.true_pose
    hardware.advance(0.1)
    after = hardware.true_pose
    run.length += math.dist(before[:2], after[:2])
    run.turning += abs(math.remainder(after[2] - before[2], 2 * math.pi))
    _measure_contact(run, crowd)
    if run.arrived_at is not None or run.failed:
        hardware.command(0.0, 0.0)
        return
    points = run.seen.update(hardware.scan(), hardware.scan_angles, hardware.odom_pose, seconds)
    obstacles = LocalObstacles(points, may_enter=run.seen.entry_check(hardware.odom_pose))
    started = time.process_time()
    drive = run.driver.drive(
        run.goal, submap, after, hardware.reported_velocity, obstacles, seconds, hardware.odom_pose
    )
    run.cycles_ms.append(1000 * (time.process_time() - started))
    hardware.command(*(drive.command or STOP))  # the agent's Driver always commands
    if drive.state is DriveState.ARRIVED:
        run.arrived_at = seconds
    elif drive.state is DriveState.FAILED:
        run.failed = drive.reason


def _measure_contact(run: RobotRun, crowd: Crowd) -> None:
    body = run.hardware.body
    gap = gap_to_others(body, crowd)
    run.min_clearance = min(run.min_clearance, gap)
    touching = gap < CONTACT or body.bumped
    if touching and not run.touching:
        run.contacts += 1
    run.touching = touching


def gap_to_others(body: Body, crowd: Crowd) -> float:
    """Metres between ``body``'s footprint and the nearest person or other robot of
    ``crowd`` (ground truth; infinite when it is alone)."""
    others = crowd.others(body)
    if not others.count:
        return math.inf
    centres = np.hypot(others.x - body.pose[0], others.y - body.pose[1])
    return float((centres - others.radius).min()) - body.radius


def _result(scenario: str, runs: list[RobotRun]) -> TrialResult:
    success = all(r.arrived_at is not None for r in runs)
    times = [r.arrived_at for r in runs if r.arrived_at is not None]
    length = sum(r.length for r in runs) / len(runs)
    turning = sum(r.turning for r in runs) / len(runs)
    return TrialResult(
        scenario,
        success,
        sum(r.contacts for r in runs),
        min(r.min_clearance for r in runs),
        max(times) if success else None,
        length,
        turning / length if length else 0.0,
        [ms for r in runs for ms in r.cycles_ms],
    )


_SUBMAP: list[SubMap] = []


def building_submap() -> SubMap:
    """The whole demo building as one map the driver plans on."""
    if not _SUBMAP:
        building = demo_building()
        origin = (*building.world_origin, 0.0)
        _SUBMAP.append(
            SubMap(
                "bench",
                "building",
                "1",
                "",
                np.array(building.world),
                building.resolution,
                origin,
                {},
                (),
                (),
            )
        )
    return _SUBMAP[0]


# --- summary ---------------------------------------------------------------------------


def summarise(results: list[TrialResult], options: dict[str, Any]) -> dict[str, Any]:
    """The JSON object: totals over every trial, then per scenario."""
    summary = {
        "planner": options["planner"],
        "sensors": options.get("sensors", "laser"),
        "seed": options["seed"],
        **_figures(results),
    }
    head_on = [r for r in results if r.scenario == "head_on"]
    summary["head_on_trials"] = len(head_on)
    summary["head_on_passes"] = sum(r.success and r.collisions == 0 for r in head_on)
    scenarios = dict.fromkeys(r.scenario for r in results)
    summary["scenarios"] = {
        name: _figures([r for r in results if r.scenario == name]) for name in scenarios
    }
    return summary


def _figures(results: list[TrialResult]) -> dict[str, Any]:
    cycles = sorted(ms for r in results for ms in r.cycles_ms)
    times = [r.time for r in results if r.time is not None]
    clearance = min((r.min_clearance for r in results), default=math.inf)
    return {
        "trials": len(results),
        "success_rate": round(sum(r.success for r in results) / len(results), 3),
        "collisions": sum(r.collisions for r in results),
        "min_clearance_m": round(clearance, 3) if math.isfinite(clearance) else None,
        "mean_time_s": round(statistics.fmean(times), 2) if times else None,
        "path_length_m": round(statistics.fmean(r.length for r in results), 2),
        "smoothness_rad_per_m": round(statistics.fmean(r.smoothness for r in results), 3),
        "cycle_p50_ms": round(_quantile(cycles, 0.5), 2),
        "cycle_p95_ms": round(_quantile(cycles, 0.95), 2),
        "cycle_max_ms": round(cycles[-1], 2) if cycles else 0.0,
    }


def _quantile(values: list[float], q: float) -> float:
    return float(np.quantile(values, q)) if values else 0.0


def table(summary: dict[str, Any]) -> str:
    keys = (
        "trials",
        "success_rate",
        "collisions",
        "min_clearance_m",
        "mean_time_s",
        "path_length_m",
        "smoothness_rad_per_m",
        "cycle_p50_ms",
        "cycle_p95_ms",
    )
    lines = [
        f"planner {summary['planner']}, seed {summary['seed']}",
        "scenario      " + " ".join(f"{k:>20}" for k in keys),
    ]
    for name, figures in [*summary["scenarios"].items(), ("all", summary)]:
        lines.append(f"{name:<14}" + " ".join(f"{figures[k]!s:>20}" for k in keys))
    lines.append(f"head-on passes: {summary['head_on_passes']} of {summary['head_on_trials']}")
    return "\n".join(lines)
