"""The first paper's Table 3, extended: a robot woken at seeded random poses across the
demo building, four ways to start its filter (``bench relocalise --table3``).

Each trial wakes the robot at a random free pose (0.4 m from anything solid) in some
sub-map; it turns on the spot (0.4 rad/s, as a robot looking around does) for 60
simulated seconds with noisy odometry and its 360-degree laser, and four particle
filters on that sub-map's grid ride along, fed the same odometry and scans:

* **tag**: the camera looks while the robot turns; the first marker detected within 2 m
  resets the filter from the stored tag (``robots.agent.relocalise``); no marker within
  reach, no pose (the trial counts as not localised);
* **visual**: the robot asks the keyframe map with its view, and every 60 degrees of turn
  again until it is answered (``maps.domain.relocalisation``); the filter starts from the
  answer and its covariance, composed with the odometry since that view;
* **random**: a pose drawn uniformly over the sub-map's free cells, any heading, with a
  covariance of 1 m and 30 degrees;
* **global**: AMCL's global localisation, particles spread over the sub-map's free cells.

Measured at 30 s and 60 s: the mean absolute error in x and y, and the filter's own
variances of x, y and yaw (mean over trials: what the paper's table reports, in m^2 and
rad^2); over the run, the share of trials within 0.25 m and 5 degrees at 60 s and the
median time to the first such pose.
"""

from __future__ import annotations

import math
import multiprocessing
import statistics
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from benchmarks.relocalise import SUCCESS, Result, _free_poses, _query, _submap_of, survey
from cloudnav_core.camera import Intrinsics, Mount
from cloudnav_core.se2 import Pose
from maps.domain.demo_building import DemoBuilding, demo_building
from maps.domain.keyframes import FeatureExtractor
from maps.domain.relocalisation import KeyframeIndex, relocalise
from maps.domain.vocabulary import default_vocabulary
from robots.agent.experiments.localisation import SENSORS, random_guess, submap_grid
from robots.agent.localisation import ParticleFilter, odometry_delta
from robots.agent.perception import TagDetector
from robots.agent.relocalise import relocalise as tag_pose
from robots.agent.sim.body import DiffDriveBody
from robots.agent.sim.camera import Camera
from robots.agent.sim.laser import Laser
from robots.agent.sim.world import World, demo_world

STARTS = ("tag", "visual", "random", "global")
CHECKPOINTS = (30.0, 60.0)
TURN_RATE = 0.4
ODOMETRY_HZ = 10.0
LASER_HZ = 5.0
CAMERA_HZ = 5.0
TAG_REACH = 2.0
ASK_EVERY = math.radians(60.0)
PAPER = {  # (measure, start, seconds): the paper's figure
    ("mean_x", "tag", 60.0): 0.09, ("mean_y", "tag", 60.0): 0.28,
    ("mean_x", "random", 60.0): 13.08, ("mean_y", "random", 60.0): 14.09,
    ("mean_x", "global", 60.0): 7.32, ("mean_y", "global", 60.0): 21.61,
    ("var_x", "tag", 30.0): 1.83e-4, ("var_x", "tag", 60.0): 5.29e-4,
    ("var_y", "tag", 30.0): 1.43e-5, ("var_y", "tag", 60.0): 2.07e-5,
    ("var_yaw", "tag", 30.0): 1.31e-5, ("var_yaw", "tag", 60.0): 5.93e-5,
    ("var_x", "random", 30.0): 1.15e-1, ("var_x", "random", 60.0): 1.50e-1,
    ("var_y", "random", 30.0): 3.10e-1, ("var_y", "random", 60.0): 5.57e-2,
    ("var_yaw", "random", 30.0): 1.39e-3, ("var_yaw", "random", 60.0): 2.98e-3,
    ("var_x", "global", 30.0): 43.36, ("var_x", "global", 60.0): 60.44,
    ("var_y", "global", 30.0): 16.21, ("var_y", "global", 60.0): 24.50,
    ("var_yaw", "global", 30.0): 0.06, ("var_yaw", "global", 60.0): 0.06,
}  # fmt: skip


@dataclass
class Outcome:
    """One start's record in one trial: per checkpoint the error (x, y) and the filter's
    variances (x, y, yaw); when it was first good; whether it had a pose at all."""

    errors: dict[float, tuple[float, float, float]] = field(default_factory=dict)
    variances: dict[float, tuple[float, float, float]] = field(default_factory=dict)
    first_good: float | None = None
    started_at: float | None = None


@dataclass
class _Start:
    name: str
    filter: ParticleFilter
    outcome: Outcome
    ready: bool = False


_SHARED: tuple[DemoBuilding, World, KeyframeIndex] | None = None
"""The building, world and surveyed keyframes the trials share (forked workers inherit
them rather than receive a copy)."""


def run_table(seed: int, trials: int, keyframes: int, workers: int = 1) -> dict[str, Any]:
    """Every trial (on ``workers`` forked processes: each trial has its own seed, so the
    figures do not depend on how many), then the table's figures as one JSON-ready object."""
    global _SHARED
    building, world = demo_building(), demo_world(seed=seed)
    index = survey(building, world, keyframes, seed, Result(seed))
    rng = np.random.default_rng([seed, 3])
    jobs = [
        (pose, seed * 1000 + trial) for trial, pose in enumerate(_free_poses(world, rng, trials))
    ]
    _SHARED = (building, world, index)
    if workers > 1:
        with multiprocessing.get_context("fork").Pool(workers) as pool:
            results = pool.starmap(_trial, jobs)
    else:
        results = [_trial(*job) for job in jobs]
    outcomes: dict[str, list[Outcome]] = {name: [] for name in STARTS}
    for result in results:
        for name, outcome in result.items():
            outcomes[name].append(outcome)
    return summary(outcomes, trials)


def _trial(pose: Pose, seed: int) -> dict[str, Outcome]:
    assert _SHARED is not None
    building, world, index = _SHARED
    return wake_up(building, world, index, pose, seed)


def wake_up(
    building: DemoBuilding, world: World, index: KeyframeIndex, truth: Pose, seed: int
) -> dict[str, Outcome]:
    """One trial: the robot turns on the spot at ``truth`` for 60 s; four filters."""
    code = _submap_of(building, truth[:2])
    grid, resolution, origin = submap_grid(building, code)
    starts = {
        name: _Start(name, ParticleFilter(grid, resolution, origin, seed=seed * 10 + i), Outcome())
        for i, name in enumerate(STARTS)
    }
    rng = np.random.default_rng(seed)
    _initial_random(starts["random"], grid, resolution, origin, rng)
    starts["global"].filter.reset_uniform()
    for name in ("random", "global"):
        starts[name].ready, starts[name].outcome.started_at = True, 0.0
    _run(world, truth, seed, starts, building, index)
    return {name: start.outcome for name, start in starts.items()}


def _initial_random(
    start: _Start,
    grid: Any,
    resolution: float,
    origin: tuple[float, float, float],
    rng: np.random.Generator,
) -> None:
    free = np.argwhere(np.asarray(grid) == 0)
    row, col = free[rng.integers(len(free))]
    guess = (
        origin[0] + (col + 0.5) * resolution,
        origin[1] + (row + 0.5) * resolution,
        float(rng.uniform(-math.pi, math.pi)),
    )
    _, covariance = random_guess(guess, rng)
    start.filter.reset(guess, covariance)


def _run(
    world: World,
    truth: Pose,
    seed: int,
    starts: dict[str, _Start],
    building: DemoBuilding,
    index: KeyframeIndex,
) -> None:
    body = DiffDriveBody(world, truth, seed=seed)
    laser, camera = Laser(world, seed=seed), Camera(world, seed=seed)
    detector, extractor = TagDetector(read_qr=False), FeatureExtractor(default_vocabulary())
    tags = {t.marker_id: t for t in building.tags}
    previous, asked_at = body.odom_pose, -math.inf
    for tick in range(1, round(max(CHECKPOINTS) * ODOMETRY_HZ) + 1):
        body.command(0.0, TURN_RATE)
        body.advance(1.0 / ODOMETRY_HZ)
        delta, previous = odometry_delta(previous, body.odom_pose), body.odom_pose
        seconds = tick / ODOMETRY_HZ
        scan = (
            SENSORS[0].message(laser, body.pose, body.time)
            if tick % round(ODOMETRY_HZ / LASER_HZ) == 0
            else None
        )
        for start in starts.values():
            if start.ready:
                start.filter.predict(delta)
                if scan is not None:
                    start.filter.update(scan)
        if tick % round(ODOMETRY_HZ / CAMERA_HZ) == 0:
            image = camera.render(body.pose)
            if not starts["tag"].ready:
                _try_tag(starts["tag"], detector.detect(image), tags, seconds)
            if not starts["visual"].ready and seconds - asked_at >= ASK_EVERY / TURN_RATE:
                asked_at = seconds
                frame = _query(extractor, camera, body.pose)
                answer = relocalise(index, [frame], Intrinsics(), Mount())
                if answer.localised:
                    starts["visual"].filter.reset(answer.pose, answer.covariance)
                    starts["visual"].ready, starts["visual"].outcome.started_at = True, seconds
        _record(starts, body.pose, seconds)


def _try_tag(start: _Start, detections: list[Any], tags: dict[int, Any], seconds: float) -> None:
    near = [d for d in detections if d.distance <= TAG_REACH and d.marker_id in tags]
    if not near:
        return
    nearest = min(near, key=lambda d: d.distance)
    estimate = tag_pose(tags[nearest.marker_id], nearest)
    start.filter.reset((estimate.x, estimate.y, estimate.yaw), estimate.covariance)
    start.ready, start.outcome.started_at = True, seconds


def _record(starts: dict[str, _Start], truth: Pose, seconds: float) -> None:
    for start in starts.values():
        if not start.ready:
            continue
        x, y, yaw = start.filter.pose()
        error = (
            abs(x - truth[0]),
            abs(y - truth[1]),
            abs(math.remainder(yaw - truth[2], math.tau)),
        )
        good = math.hypot(error[0], error[1]) <= SUCCESS[0] and error[2] <= SUCCESS[1]
        if good and start.outcome.first_good is None:
            start.outcome.first_good = seconds
        for moment in CHECKPOINTS:
            if abs(seconds - moment) < 1e-6:
                covariance = start.filter.covariance()
                start.outcome.errors[moment] = error
                start.outcome.variances[moment] = (
                    covariance[0, 0],
                    covariance[1, 1],
                    covariance[2, 2],
                )


def summary(outcomes: dict[str, list[Outcome]], trials: int) -> dict[str, Any]:
    table: dict[str, Any] = {"trials": trials, "starts": {}}
    for name, records in outcomes.items():
        row: dict[str, Any] = {"localised_trials": sum(1 for r in records if r.errors)}
        for moment in CHECKPOINTS:
            # A start that had no pose yet at a checkpoint counts only from the next one.
            posed = [r for r in records if moment in r.errors]
            tag = f"{moment:g}s"
            row[f"trials_{tag}"] = len(posed)
            row[f"mean_x_{tag}"] = _mean([r.errors[moment][0] for r in posed])
            row[f"mean_y_{tag}"] = _mean([r.errors[moment][1] for r in posed])
            for axis, label in enumerate(("x", "y", "yaw")):
                row[f"var_{label}_{tag}"] = _mean([r.variances[moment][axis] for r in posed])
        end = max(CHECKPOINTS)
        good = [
            r
            for r in records
            if end in r.errors
            and math.hypot(*r.errors[end][:2]) <= SUCCESS[0]
            and r.errors[end][2] <= SUCCESS[1]
        ]
        row["success_rate_60s"] = len(good) / trials if trials else 0.0
        times = [r.first_good for r in records if r.first_good is not None]
        row["time_to_good_pose_s"] = statistics.median(times) if times else None
        table["starts"][name] = row
    table["paper"] = {f"{m}_{s}_{t:g}s": v for (m, s, t), v in PAPER.items()}
    return table


def _mean(values: list[float]) -> float | None:
    return float(statistics.fmean(values)) if values else None


def format_table(table: dict[str, Any]) -> str:
    """The table beside the paper's figures (paper in brackets; n/a where it has none)."""
    lines = [f"Wake-ups at {table['trials']} random poses, 60 s turning on the spot", ""]
    header = "| measure | " + " | ".join(f"{s} 30 s | {s} 60 s" for s in STARTS) + " |"
    lines += [header, "|" + "---|" * (1 + 2 * len(STARTS))]
    for measure in ("mean_x", "mean_y", "var_x", "var_y", "var_yaw"):
        cells = []
        for start in STARTS:
            for moment in CHECKPOINTS:
                ours = table["starts"][start][f"{measure}_{moment:g}s"]
                paper = PAPER.get((measure, start, moment))
                cells.append(f"{_figure(ours)} ({_figure(paper)})")
        lines.append(f"| {measure} | " + " | ".join(cells) + " |")
    for start in STARTS:
        row = table["starts"][start]
        lines.append(
            f"{start}: {row['localised_trials']}/{table['trials']} had a pose; "
            f"{row['success_rate_60s']:.0%} within 0.25 m and 5 degrees at 60 s; "
            f"median time to a good pose {_figure(row['time_to_good_pose_s'])} s"
        )
    return "\n".join(lines)


def _figure(value: float | None) -> str:
    if value is None:
        return "n/a"
    return f"{value:.3g}"
