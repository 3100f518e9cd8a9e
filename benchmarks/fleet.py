"""Fleet rules against robots planning alone: patrol missions through the demo building.

``--robots`` simulated robots (``robots.agent.fleet``) start parked, as a fleet does: at
the demo building's parking spots, taken a sub-map at a time in turn (Atria 1 to 3,
Rooms A and B), any beyond its 12 in two rows in Corridor A, each placed where it stands
(no camera: the simulation keeps its pace on a busy machine; the particle filters and
lasers run as ``make demo``'s do), among ``--people`` people walking seeded routes
through the building (the navigation bench's crowd). Each is given one patrol mission
over the REST API: the main spaces of ``TOUR`` (the mapping bench's tour), starting at a
different one per robot and every other robot going round the other way, so they meet
head on in corridors and doorways and are sent to the same places. A waypoint not
reached within ``--time-limit`` seconds of the robot's clock is skipped (the mission's own
rule); a mission paused by a refusal or a failure is told to skip and resume, as an
operator would.

It runs twice in one bench, each on its own scratch server (``benchmarks.agent.demo_server``)
for ``--minutes`` simulated minutes of every robot: with the fleet rules (the building's
defaults: reserved destinations, ``fleet_rule`` ``move``, parking, and every rule
switched on by default) and alone (``fleet_rule`` ``off``, and the server's settings in
``ALONE_SETTINGS`` off: goals go where asked, the robots sort it out among themselves).
The demo building's parking spots are seeded, but a robot on a mission is never parked
(its next waypoint moves it on), so none is parked here. Figures, in
both the top level (rules) and ``alone``:

- ``waypoints_reached``: goals the robots reported reached (ground truth: the robot's
  own goal board), a moved goal's free spot included;
- ``waypoints_refused_or_moved``: goals the server moved to a free spot (its
  ``goal_sent`` events say so) plus waypoints refused (the mission paused with the reason);
- ``deadlocks``: times a robot with a goal made no progress (came no 0.25 m nearer its
  goal than before) for 60 simulated seconds;
- ``collisions``: contacts from the simulator's ground truth (a robot's footprint
  touching a person or another robot, or its bumper stopping it at a wall), sampled
  every ``SAMPLE_S`` wall seconds, counted per robot as the navigation bench does;
- ``mean_wait_s``: simulated seconds a robot with a goal stood still (under 5 cm/s),
  per waypoint ended (reached, timed out or failed);
- ``throughput_per_hour``: waypoints reached per simulated hour, the whole fleet;
- ``cloud_cpu``: the server process's CPU over the run, in cores.

``python manage.py bench fleet --robots 10 --seed 1 --json`` prints one JSON object.
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import itertools
import json
import logging
import math
import os
import sys
import time
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Any

import httpx
import psutil

from benchmarks.agent import demo_server
from benchmarks.mapping import TOUR, admin_password
from benchmarks.navigation import CONTACT, gap_to_others
from cloudnav_core.messages import GoalStatus
from cloudnav_core.params import RobotConfig
from cloudnav_core.se2 import Point, Pose
from maps.domain.demo_building import DemoParking, demo_building, space_interiors
from maps.domain.reservations import FleetRule
from robots.agent.fleet import FleetOptions, FleetRobot, build_fleet, place_at_truth, run_fleet
from robots.agent.sim.world import demo_world
from robots.agent.supervisor.submaps import BundleError

BUILDING = "boccioni_1"
ROWS_MAP = f"{BUILDING}/CorridorA"
STARTS_X, STARTS_STEP, STARTS_Y = 4.6, 1.1, (22.7, 23.7)
"""Where robots beyond the parking spots begin: two rows along Corridor A, 1.1 m apart,
1 m between rows."""
MAX_ROBOTS = 2 * 12
SAMPLE_S = 0.1
"""Wall seconds between the ground-truth samples."""
STUCK_S = 60.0
"""Simulated seconds without progress that make a deadlock."""
PROGRESS_M = 0.25
STILL_M_S = 0.05
RULES: dict[str, Any] = {"fleet_rule": FleetRule.MOVE.value}
ALONE: dict[str, Any] = {"fleet_rule": FleetRule.OFF.value}
"""What the building is set to for each run (every other fleet switch at its default)."""
ALONE_SETTINGS = {"CLOUDNAV_RIGHT_OF_WAY": "0"}
"""The server's settings for the robots planning alone: the fleet rules switched by
setting rather than by the building's (right of way in narrow places, where merged)."""
HTTP_TIMEOUT = 30.0
ASKS = 10
DETECT_RATE = 2.0
"""Frames/s rendered for the tag detector (robots cross doorways by their tags); none sent."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--robots", type=int, default=10, help=f"robots (at most {MAX_ROBOTS})")
    parser.add_argument("--seed", type=int, default=1, help="seed of the people and the robots")
    parser.add_argument("--minutes", type=float, default=30.0, help="simulated minutes a run")
    parser.add_argument("--time-scale", type=float, default=1.0, help="simulated s per wall s")
    parser.add_argument("--people", type=int, default=8, help="people walking in the building")
    parser.add_argument(
        "--time-limit",
        type=float,
        default=300.0,
        help="s of its robot's clock a waypoint may take, then skipped",
    )
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    parser.add_argument(
        "--url", help="a running server's http:// base (both runs on it) instead of scratch ones"
    )
    parser.add_argument("--tokens-file", help="with --url: seed_demo's tokens JSON")


def run(options: dict[str, Any]) -> None:
    logging.getLogger("httpx").setLevel(logging.WARNING)  # a request a second, every robot
    if not 1 <= options["robots"] <= MAX_ROBOTS:
        raise SystemExit(f"--robots: 1 to {MAX_ROBOTS}")
    rules = asyncio.run(measure(options, RULES))
    with _settings(ALONE_SETTINGS):
        alone = asyncio.run(measure(options, ALONE))
    summary = {
        "robots": options["robots"],
        "seed": options["seed"],
        "people": options["people"],
        "minutes": options["minutes"],
        "time_scale": options["time_scale"],
        **rules,
        "alone": alone,
    }
    print(json.dumps(summary) if options["json"] else table(summary))


@contextlib.contextmanager
def _settings(values: dict[str, str]) -> Iterator[None]:
    """The scratch servers started meanwhile get ``values`` in their environment."""
    before = {key: os.environ.get(key) for key in values}
    os.environ.update(values)
    try:
        yield
    finally:
        for key, value in before.items():
            if value is None:
                os.environ.pop(key, None)
            else:
                os.environ[key] = value


# --- one run ---------------------------------------------------------------------------


@dataclass
class Watch:
    """What the bench saw of one robot (simulated seconds, ground truth)."""

    member: FleetRobot
    seconds: float = 0.0
    counted: set[str] = field(default_factory=set)  # goal ids whose end was counted
    reached: int = 0
    ended: int = 0
    waited: float = 0.0
    contacts: int = 0
    touching: bool = False
    goal: Pose | None = None
    best: float = math.inf
    progress_at: float = 0.0
    deadlocks: int = 0

    def sample(self) -> None:
        robot = self.member.robot
        dt, self.seconds = robot.seconds - self.seconds, robot.seconds
        self._contact()
        self._goals()
        if robot.navigator.board.active is None:
            self.goal = None
            return
        if abs(robot.hardware.body.velocity[0]) < STILL_M_S:
            self.waited += dt
        self._progress()

    def _contact(self) -> None:
        hardware = self.member.robot.hardware
        gap = math.inf if hardware.crowd is None else gap_to_others(hardware.body, hardware.crowd)
        touching = gap < CONTACT or hardware.body.bumped
        if touching and not self.touching:
            self.contacts += 1
            what = "a wall (bumper)" if hardware.body.bumped else f"a person or robot {gap:.3f} m"
            self._say(f"contact with {what}")
        self.touching = touching

    def _say(self, what: str) -> None:
        """Tell the bench log what happened to this robot, where and what it was doing."""
        robot = self.member.robot
        x, y, _ = robot.hardware.true_pose
        active = robot.navigator.board.active
        doing = active.text if active is not None else "no goal"
        print(
            f"fleet: {self.member.name} {what} at ({x:.2f}, {y:.2f}) t={self.seconds:.0f} s: "
            f"{doing}",
            file=sys.stderr,
        )

    def _goals(self) -> None:
        for entry in self.member.robot.navigator.board.entries:
            if entry.status.terminal and entry.goal_id not in self.counted:
                self.counted.add(entry.goal_id)
                self.ended += 1
                self.reached += entry.status is GoalStatus.SUCCEEDED

    def _progress(self) -> None:
        destination = self.member.robot.supervisor.destination
        goal = destination.pose if destination is not None else None
        here = self.member.robot.hardware.true_pose
        if goal != self.goal:
            self.goal, self.best, self.progress_at = goal, math.inf, self.seconds
        if goal is None:
            return
        away = math.dist(here[:2], goal[:2])
        if away < self.best - PROGRESS_M:
            self.best, self.progress_at = away, self.seconds
        elif self.seconds - self.progress_at >= STUCK_S:
            self.deadlocks += 1
            self._say(f"deadlock: {away:.1f} m from its goal ({goal[0]:.2f}, {goal[1]:.2f})")
            self.progress_at = self.seconds  # the next one after another minute stuck


async def measure(options: dict[str, Any], building: dict[str, Any]) -> dict[str, Any]:
    """One run with the building set to ``building``: its figures (see the module)."""
    count = options["robots"]
    server = {"url": options.get("url"), "tokens_file": options.get("tokens_file"), "robots": count}
    with demo_server(server) as (url, tokens):
        async with httpx.AsyncClient(
            base_url=url,
            auth=("admin", admin_password()),
            timeout=HTTP_TIMEOUT,
            limits=httpx.Limits(max_keepalive_connections=0),  # see _ask
        ) as http:
            await _ask(http, "PATCH", f"/api/buildings/{BUILDING}/", json=building)
            fleet = build_fleet(list(tokens.items())[:count], fleet_options(url, options))
            running = asyncio.create_task(run_fleet(fleet, options["time_scale"]))
            try:
                await _placed(fleet)
                process = _server_process(url)
                cpu, wall = _cpu_seconds(process), time.monotonic()
                watches = [Watch(member) for member in fleet]
                missions = await _start_patrols(http, fleet, options)
                refused, failed = await _watch(http, watches, missions, options)
                cpu, wall = _cpu_seconds(process) - cpu, time.monotonic() - wall
            finally:
                running.cancel()
                with contextlib.suppress(asyncio.CancelledError):
                    await running
            moved = await _count_events(http, "goal_sent", "Moved to the nearest free spot")
            timed_out = await _count_events(http, "waypoint_timed_out")
    return _figures(watches, moved, refused, failed, timed_out, cpu, wall)


async def _placed(fleet: list[FleetRobot]) -> None:
    """Place every robot where it stands (``place_at_truth``), asking again when the loaded
    server dropped a bundle's connection (placing a robot twice is harmless)."""
    map_ids = [start(index)[0] for index in range(len(fleet))]
    for attempt in range(1, ASKS + 1):
        try:
            await place_at_truth(fleet, map_ids)
            return
        except BundleError:
            if attempt == ASKS:
                raise
            await asyncio.sleep(2 * attempt)


def fleet_options(url: str, options: dict[str, Any]) -> FleetOptions:
    config = RobotConfig(camera_rate=0, depth_rate=0, detect_rate=DETECT_RATE)
    return FleetOptions(
        url,
        seed=options["seed"],
        robot=config,
        visual=False,
        people=options["people"],
        people_seed=options["seed"],
        starts=tuple(start(index)[1] for index in range(options["robots"])),
    )


def start(index: int) -> tuple[str, Pose]:
    """Robot ``index``'s sub-map and start (see the module): a parking spot, else a place
    in Corridor A's rows, facing east."""
    spots = _parking_in_turn()
    if index < len(spots):
        spot = spots[index]
        return f"{BUILDING}/{spot.submap}", (spot.x, spot.y, spot.yaw)
    row = index - len(spots)
    return ROWS_MAP, (STARTS_X + STARTS_STEP * (row // 2), STARTS_Y[row % 2], 0.0)


def _parking_in_turn() -> list[DemoParking]:
    """The demo building's parking spots, one sub-map's after another's in turn."""
    by_submap: dict[str, list[DemoParking]] = {}
    for spot in demo_building().parking:
        by_submap.setdefault(spot.submap, []).append(spot)
    rounds = itertools.zip_longest(*by_submap.values())
    return [spot for spots in rounds for spot in spots if spot is not None]


def patrol(index: int) -> list[dict[str, Any]]:
    """Robot ``index``'s waypoints: a free spot near the middle of each space of ``TOUR``,
    from its own first one; every other robot goes round the other way."""
    order = [*TOUR[index % len(TOUR) :], *TOUR[: index % len(TOUR)]]
    if index % 2:
        order.reverse()
    return [{"map": code, "x": x, "y": y, "yaw": 0.0} for code in order for x, y in [_middle(code)]]


def _middle(code: str) -> Point:
    """The free spot nearest the middle of sub-map ``code``'s main space (some have a pillar
    or a table there)."""
    x0, y0, x1, y1 = space_interiors()[code][0]
    world, centre = demo_world(), ((x0 + x1) / 2, (y0 + y1) / 2)
    for ring, k in itertools.product(range(40), range(16)):
        angle, reach = 2 * math.pi * k / 16, 0.1 * ring
        spot = (centre[0] + reach * math.cos(angle), centre[1] + reach * math.sin(angle))
        if world.disc_is_free(spot[0], spot[1], 0.45):
            return spot
    raise RuntimeError(f"no free spot near the middle of {code}")


async def _start_patrols(
    http: httpx.AsyncClient, fleet: list[FleetRobot], options: dict[str, Any]
) -> list[int]:
    missions = []
    for index, member in enumerate(fleet):
        answer = await _ask(
            http,
            "POST",
            "/api/missions/",
            json={
                "building": BUILDING,
                "robot": member.name,
                "name": f"patrol {index}",
                "mode": "patrol",
                "waypoints": patrol(index),
                "time_limit": options["time_limit"],
                "on_timeout": "skip",
            },
        )
        missions.append(int(answer.json()["id"]))
    return missions


async def _watch(
    http: httpx.AsyncClient, watches: list[Watch], missions: list[int], options: dict[str, Any]
) -> tuple[int, int]:
    """Sample every robot until each has run ``--minutes`` simulated minutes (no wall
    deadline: a loaded machine only takes longer); resume paused missions as they pause.
    Returns the waypoints refused and the goals failed (missions paused by each)."""
    seconds = 60 * options["minutes"]
    refused = failed = 0
    checked = said = time.monotonic()
    while min(w.member.robot.seconds for w in watches) < seconds:
        for watch in watches:
            watch.sample()
        if time.monotonic() - checked >= 5.0:
            checked = time.monotonic()
            more_refused, more_failed = await _resume_paused(http, missions)
            refused, failed = refused + more_refused, failed + more_failed
        if time.monotonic() - said >= 60:
            said = time.monotonic()
            clock = min(w.member.robot.seconds for w in watches)
            print(f"fleet: robots' clocks at {clock:.0f} of {seconds:.0f} s", file=sys.stderr)
        await asyncio.sleep(SAMPLE_S)
    for watch in watches:
        watch.sample()
    return refused, failed


async def _resume_paused(http: httpx.AsyncClient, missions: list[int]) -> tuple[int, int]:
    """Skip the waypoint of each paused mission and resume it; the refused and the failed."""
    answer = await _ask(http, "GET", "/api/missions/", params={"building": BUILDING})
    paused = [m for m in answer.json() if m["id"] in missions and m["state"] == "paused"]
    refused = 0
    for mission in paused:
        print(f"fleet: {mission['robot']} {mission['note']}", file=sys.stderr)
        refused += "is held" in mission["note"]
        for command in ("skip", "resume"):
            await _ask(http, "POST", f"/api/missions/{mission['id']}/{command}", check=False)
    return refused, len(paused) - refused


async def _count_events(http: httpx.AsyncClient, kind: str, saying: str = "") -> int:
    """The building's events of ``kind`` whose message holds ``saying``, every page."""
    found, until = 0, None
    while True:
        params = {"building": BUILDING, "kind": kind, "limit": "1000"}
        if until is not None:
            params["until"] = until
        answer = await _ask(http, "GET", "/api/events/", params=params)
        page = answer.json()
        found += sum(saying in event["message"] for event in page)
        if len(page) < 1000:
            return found
        until = page[-1]["time"]


async def _ask(
    http: httpx.AsyncClient, method: str, url: str, check: bool = True, **kwargs: Any
) -> httpx.Response:
    """The server's answer to a request, asked again (up to ``ASKS`` times) when the
    connection broke: the loaded scratch server sometimes closes one before answering.
    Asking again is safe: a mission started again replaces the robot's first one, and the
    rest only read or set a state. Raises HTTPStatusError for an error status (``check``)."""
    for attempt in range(1, ASKS + 1):
        try:
            answer = await http.request(method, url, **kwargs)
            break
        except httpx.TransportError:
            if attempt == ASKS:
                raise
            await asyncio.sleep(2 * attempt)
    if check:
        answer.raise_for_status()
    return answer


def _server_process(url: str) -> psutil.Process:
    """The server at ``url``: this process's daphne child listening on its port (a scratch
    server, or a test's live server)."""
    port = url.rsplit(":", 1)[-1].strip("/")
    children = psutil.Process().children()
    return next(c for c in children if "daphne" in (line := " ".join(c.cmdline())) and port in line)


def _cpu_seconds(process: psutil.Process) -> float:
    times = process.cpu_times()
    return float(times.user + times.system)


def _figures(
    watches: list[Watch],
    moved: int,
    refused: int,
    failed: int,
    timed_out: int,
    cpu: float,
    wall: float,
) -> dict[str, Any]:
    simulated = min(w.seconds for w in watches)
    reached = sum(w.reached for w in watches)
    ended = sum(w.ended for w in watches)
    return {
        "waypoints_reached": reached,
        "waypoints_refused_or_moved": refused + moved,
        "deadlocks": sum(w.deadlocks for w in watches),
        "collisions": sum(w.contacts for w in watches),
        "mean_wait_s": round(sum(w.waited for w in watches) / max(1, ended), 1),
        "throughput_per_hour": round(reached / max(simulated, 1e-9) * 3600, 1),
        "cloud_cpu": round(cpu / wall, 3),
        "waypoints_moved": moved,
        "waypoints_refused": refused,
        "waypoints_timed_out": timed_out,
        "goals_failed": failed,
        "simulated_min": round(simulated / 60, 2),
        "wall_min": round(wall / 60, 2),
        "load_average": round(os.getloadavg()[0], 1),
    }


KEYS = (
    "waypoints_reached",
    "waypoints_refused_or_moved",
    "deadlocks",
    "collisions",
    "mean_wait_s",
    "throughput_per_hour",
    "cloud_cpu",
    "waypoints_timed_out",
    "simulated_min",
    "wall_min",
)


def table(summary: dict[str, Any]) -> str:
    lines = [
        f"{summary['robots']} robots, {summary['people']} people, seed {summary['seed']}",
        f"{'':<28}{'fleet rules':>14}{'alone':>14}",
    ]
    lines += [f"{key:<28}{summary[key]!s:>14}{summary['alone'][key]!s:>14}" for key in KEYS]
    return "\n".join(lines)
