"""Visual relocalisation: wake-ups without a tag in the demo building, on keyframes.

The demo building's walls are textured from ``--seed``. A survey lays ``--keyframes``
keyframes over its free space (random positions at least 0.3 m from walls, random
headings; each keyframe's pose carries the error of a robot localised by tags and its
filter: 2 cm and 0.5 degrees), each rendered with depth and ingested as the server does
(ORB, 3D points, bag of words). Then ``--trials`` wake-ups at seeded random poses, none
a keyframe's: the robot asks with one image and, while not localised, turns 60 degrees
and asks again with every image so far (at most six), as the agent does. A wake-up
succeeds when the answer is within 0.25 m and 5 degrees of the truth; the sub-map is
right when the answer's sub-map holds the true position. An answer is confidently wrong
when it misses by more than that and its claimed covariance still excludes the truth
(squared Mahalanobis distance past ``CHI2_99``, the chi-square bound for 3 DoF at 99 %);
``outside_ellipse`` counts every answer whose 99 % ellipse misses the truth.

Wrong building: the same wake-ups in another building (the demo floor plan under
another code: every wall looks different) asked against this building's keyframes;
every answer given is counted.

Times are one query of one image on this process's one thread (the server answers one
query per worker thread), and one keyframe's ingestion (features, points, words).
Keyframes on the wire: the agent's request body (JPEG, depth as ROS's
``compressedDepth`` PNG, camera, pose) beside the same body with the depth as a raw
``sensor_msgs/Image`` (the form robots sent before), and the time to read the image and
depth back out of it.

``--solver opencv`` hypothesises poses with OpenCV's free 6-DoF ``solvePnPRansac``
instead of the level camera's RANSAC (the rest alike), to compare the two.

Run: ``python manage.py bench relocalise --seed 1 --json``; ``--table3`` runs the first
paper's Table 3 instead (``benchmarks/wakeup_table.py``).
"""

from __future__ import annotations

import argparse
import json
import math
import statistics
import time
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Any

import cv2
import numpy as np

from cloudnav_core.camera import CameraModel, Intrinsics, Mount
from cloudnav_core.messages import depth_image
from maps.domain.demo_building import DemoBuilding, DemoSubMap, demo_building
from maps.domain.keyframes import Depth, FeatureExtractor, Image
from maps.domain.relocalisation import Answer, KeyframeIndex, Params, QueryFrame, relocalise
from maps.domain.visual_input import depth_image as depth_of_image
from maps.domain.visual_input import grey_image
from maps.domain.vocabulary import default_vocabulary
from maps.exceptions import KeyframeError
from robots.agent.sim.camera import Camera
from robots.agent.sim.world import World, demo_world
from robots.agent.visual import keyframe_document

CLEARANCE = 0.3
KEYFRAME_POSE_ERROR = (0.02, math.radians(0.5))
SUCCESS = (0.25, math.radians(5.0))
TURN = math.radians(60.0)
MAX_VIEWS = 6
OTHER_BUILDING = "other_1"
CHI2_99 = 11.34
PIXEL_LIMIT = 640 * 480


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--seed", type=int, default=1, help="wake-up poses and wall textures")
    parser.add_argument("--trials", type=int, default=50, help="wake-ups")
    parser.add_argument("--keyframes", type=int, default=1000, help="keyframes surveyed")
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    parser.add_argument(
        "--solver", choices=("level", "opencv"), default="level",
        help="pose hypotheses: the level camera's RANSAC, or OpenCV's solvePnPRansac",
    )  # fmt: skip
    parser.add_argument(
        "--workers", type=int, default=1, help="processes running --table3's trials",
    )  # fmt: skip
    parser.add_argument(
        "--table3", action="store_true",
        help="the paper's Table 3 instead: tag, visual, random and global starts compared",
    )  # fmt: skip


def run(options: dict[str, Any]) -> None:
    if options["table3"]:
        from benchmarks.wakeup_table import format_table, run_table

        table = run_table(
            options["seed"], options["trials"], options["keyframes"], options["workers"]
        )
        print(json.dumps(table) if options["json"] else format_table(table))
        return
    params = Params(solver=options["solver"])
    result = measure(options["seed"], options["trials"], options["keyframes"], params)
    print(json.dumps(result.summary()) if options["json"] else report(result))


@dataclass
class Result:
    seed: int
    solver: str = "level"
    keyframes: int = 0
    trials: int = 0
    successes: int = 0
    right_submap: int = 0
    answered: int = 0
    views: list[int] = field(default_factory=list)
    errors: list[tuple[float, float]] = field(default_factory=list)
    query_ms: list[float] = field(default_factory=list)
    ingest_ms: list[float] = field(default_factory=list)
    stored_bytes: list[int] = field(default_factory=list)
    wire_bytes: list[int] = field(default_factory=list)
    wire_bytes_raw_depth: list[int] = field(default_factory=list)
    wire_read_ms: list[float] = field(default_factory=list)
    confident_wrong: int = 0
    outside_ellipse: int = 0
    wrong_trials: int = 0
    wrong_answers: int = 0
    wrong_sigmas: list[float] = field(default_factory=list)

    def summary(self) -> dict[str, Any]:
        position = [e[0] for e in self.errors]
        return {
            "seed": self.seed,
            "solver": self.solver,
            "trials": self.trials,
            "success_rate": _rate(self.successes, self.trials),
            "submap_rate": _rate(self.right_submap, self.answered),
            "answered_rate": _rate(self.answered, self.trials),
            "mean_views": statistics.fmean(self.views) if self.views else 0.0,
            "median_position_error_m": statistics.median(position) if position else None,
            "median_yaw_error_deg": (
                math.degrees(statistics.median(e[1] for e in self.errors)) if self.errors else None
            ),
            "confident_wrong": self.confident_wrong,
            "outside_ellipse": self.outside_ellipse,
            "wrong_building_trials": self.wrong_trials,
            "wrong_building_answers": self.wrong_answers,
            "wrong_building_sigma_m": self.wrong_sigmas,
            "query_p50_ms": _percentile(self.query_ms, 50),
            "query_p95_ms": _percentile(self.query_ms, 95),
            "ingest_ms": statistics.fmean(self.ingest_ms) if self.ingest_ms else 0.0,
            "ingest_p95_ms": _percentile(self.ingest_ms, 95),
            "keyframes": self.keyframes,
            "bytes_per_keyframe": _mean_bytes(self.stored_bytes),
            "wire_bytes_per_keyframe": _mean_bytes(self.wire_bytes),
            "wire_bytes_per_keyframe_raw_depth": _mean_bytes(self.wire_bytes_raw_depth),
            "wire_read_ms": statistics.fmean(self.wire_read_ms) if self.wire_read_ms else 0.0,
        }


def measure(seed: int, trials: int, keyframes: int, params: Params | None = None) -> Result:
    cv2.setNumThreads(1)  # one core: times are this thread's CPU time
    params = params or Params()
    building = demo_building()
    world = demo_world(seed=seed)
    result = Result(seed, params.solver)
    index = survey(building, world, keyframes, seed, result)
    rng = np.random.default_rng([seed, 2])
    other = Camera(demo_world(seed=seed, building_code=OTHER_BUILDING), seed=seed + 7)
    camera = Camera(world, seed=seed + 3)
    for pose in _free_poses(world, rng, trials):
        wake_up(index, camera, building, pose, result, params)
        wrong_building(index, other, pose, result, params)
    return result


def survey(
    building: DemoBuilding, world: World, count: int, seed: int, result: Result
) -> KeyframeIndex:
    """``count`` keyframes over the building, as robots with good poses would send them."""
    vocabulary = default_vocabulary()
    extractor = FeatureExtractor(vocabulary)
    camera = Camera(world, seed=seed + 1)
    index = KeyframeIndex(vocabulary.size)
    rng = np.random.default_rng([seed, 1])
    for pose in _free_poses(world, rng, count):
        image, depth = camera.capture(pose)
        assert depth is not None
        believed = _perturbed(pose, rng)
        _wire(image, depth, believed, result)
        started = time.thread_time()
        try:
            keyframe = extractor.keyframe(image, depth, believed)
        except KeyframeError:  # a view of a blank wall too close to see
            continue
        result.ingest_ms.append(1000 * (time.thread_time() - started))
        result.stored_bytes.append(len(keyframe.to_bytes()) + 200)  # + the database row
        index.add(len(index), _submap_of(building, pose[:2]), keyframe)
    result.keyframes = len(index)
    return index


def _wire(image: Image, depth: Depth, pose: tuple[float, float, float], result: Result) -> None:
    """What the keyframe costs on the wire: the agent's request body (depth as
    ``compressedDepth``) against the same with a raw ``sensor_msgs/Image`` depth, and the
    server's time to read the image and depth out of it."""
    document = keyframe_document(CameraModel(), pose, image, depth)
    result.wire_bytes.append(len(json.dumps(document)))
    raw = {**document, "depth": depth_image("camera", depth, 0.0)}
    result.wire_bytes_raw_depth.append(len(json.dumps(raw)))
    started = time.thread_time()
    grey = grey_image(document["image"], PIXEL_LIMIT)
    depth_of_image(document["depth"], grey.shape, PIXEL_LIMIT)
    result.wire_read_ms.append(1000 * (time.thread_time() - started))


def wake_up(
    index: KeyframeIndex,
    camera: Camera,
    building: DemoBuilding,
    pose: tuple[float, float, float],
    result: Result,
    params: Params,
) -> None:
    """One wake-up: ask with one view, then turn and ask with more, until answered."""
    extractor = FeatureExtractor(default_vocabulary())
    frames: list[QueryFrame] = []
    headings: list[float] = []
    answer = Answer(False)
    result.trials += 1
    for view in range(MAX_VIEWS):
        heading = pose[2] + view * TURN
        frames.append(_query(extractor, camera, (pose[0], pose[1], heading)))
        headings.append(heading)
        started = time.thread_time()
        answer = relocalise(index, frames[-1:], Intrinsics(), Mount(), params=params)
        result.query_ms.append(1000 * (time.thread_time() - started))
        if answer.localised:
            break
    result.views.append(len(frames))
    if not answer.localised:
        return
    truth = (pose[0], pose[1], headings[-1])
    error = (
        math.hypot(answer.pose[0] - truth[0], answer.pose[1] - truth[1]),
        abs(math.remainder(answer.pose[2] - truth[2], math.tau)),
    )
    result.answered += 1
    result.errors.append(error)
    success = error[0] <= SUCCESS[0] and error[1] <= SUCCESS[1]
    result.successes += success
    outside = mahalanobis2(answer, truth) > CHI2_99
    result.outside_ellipse += outside
    result.confident_wrong += outside and not success
    result.right_submap += _holds(building, answer.submap, pose[:2])


def wrong_building(
    index: KeyframeIndex,
    camera: Camera,
    pose: tuple[float, float, float],
    result: Result,
    params: Params,
) -> None:
    """Six views of the same place in another building, each asked alone."""
    extractor = FeatureExtractor(default_vocabulary())
    for view in range(MAX_VIEWS):
        frame = _query(extractor, camera, (pose[0], pose[1], pose[2] + view * TURN))
        answer = relocalise(index, [frame], Intrinsics(), Mount(), params=params)
        result.wrong_trials += 1
        if answer.localised:
            result.wrong_answers += 1
            result.wrong_sigmas.append(
                float(math.sqrt(answer.covariance[0, 0] + answer.covariance[1, 1]))
            )


def mahalanobis2(answer: Answer, truth: tuple[float, float, float]) -> float:
    """The squared Mahalanobis distance of ``truth`` from the answer, by its covariance."""
    offset = np.array(
        [
            answer.pose[0] - truth[0],
            answer.pose[1] - truth[1],
            math.remainder(answer.pose[2] - truth[2], math.tau),
        ]
    )
    return float(offset @ np.linalg.solve(answer.covariance, offset))


def _query(
    extractor: FeatureExtractor, camera: Camera, pose: tuple[float, float, float]
) -> QueryFrame:
    pixels, descriptors = extractor.detect(camera.render(pose))
    return QueryFrame(pixels, descriptors, extractor.vocabulary.bag(descriptors))


def _free_poses(
    world: World,
    rng: np.random.Generator,
    count: int,
    within: tuple[float, float, float, float] | None = None,
) -> Iterator[tuple[float, float, float]]:
    """Seeded poses inside the building (on a free cell of some sub-map; inside
    ``within``, x0, y0, x1, y1, when given) at least ``CLEARANCE`` from anything solid."""
    building = demo_building()
    made = 0
    height, width = world.cells.shape
    while made < count:
        x = world.origin[0] + rng.uniform(0, width * world.resolution)
        y = world.origin[1] + rng.uniform(0, height * world.resolution)
        yaw = float(rng.uniform(-math.pi, math.pi))
        if not _submap_of(building, (x, y)) or not world.disc_is_free(x, y, CLEARANCE):
            continue
        if within is not None and not (within[0] <= x <= within[2] and within[1] <= y <= within[3]):
            continue
        made += 1
        yield (float(x), float(y), yaw)


def _perturbed(
    pose: tuple[float, float, float], rng: np.random.Generator
) -> tuple[float, float, float]:
    position, heading = KEYFRAME_POSE_ERROR
    dx, dy = rng.normal(0, position, 2)
    return (pose[0] + float(dx), pose[1] + float(dy), pose[2] + float(rng.normal(0, heading)))


def _window_holds(submap: DemoSubMap, point: tuple[float, float]) -> bool:
    x0, y0 = submap.origin[0], submap.origin[1]
    x1, y1 = x0 + submap.width * submap.resolution, y0 + submap.height * submap.resolution
    return x0 <= point[0] <= x1 and y0 <= point[1] <= y1


def _submap_of(building: DemoBuilding, point: tuple[float, float]) -> str:
    """The first sub-map whose window holds ``point`` ("" for none, or for a point not
    on the building's known free floor: the street, inside a wall)."""
    col = int((point[0] - building.world_origin[0]) / building.resolution)
    row = int((point[1] - building.world_origin[1]) / building.resolution)
    rows, cols = building.world.shape
    if not (0 <= row < rows and 0 <= col < cols) or building.world[row, col] != 0:
        return ""
    return next((s.code for s in building.submaps if _window_holds(s, point)), "")


def _holds(building: DemoBuilding, code: str, point: tuple[float, float]) -> bool:
    submap = next((s for s in building.submaps if s.code == code), None)
    return submap is not None and _window_holds(submap, point)


def _mean_bytes(sizes: list[int]) -> int:
    return round(statistics.fmean(sizes)) if sizes else 0


def _rate(part: int, whole: int) -> float:
    return part / whole if whole else 0.0


def _percentile(values: list[float], q: float) -> float:
    return float(np.percentile(values, q)) if values else 0.0


def report(result: Result) -> str:
    summary = result.summary()
    return "\n".join(f"{key:>26}: {value}" for key, value in summary.items())
