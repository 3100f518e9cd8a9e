"""Visual SLAM measured: a camera-only tour with loops against the truth, beside Open3D.

A seeded tour (``tour``) of the demo building: from Corridor A's west end east along it,
through the door into Atrium 1, once around the atrium outside its pillars, back down
Corridor A, a half turn; ``--laps`` times (2: 104 m, 1,250 frames). The simulated
robot's camera (``Camera.capture``: grey image and registered depth, wall textures and
sensor noise from ``--seed``) takes a frame every 0.1 m and every 10 degrees (a robot at
0.5 m/s and 50 degrees/s whose camera runs at 5 frames/s, with depth on every frame: the
simulated robot's ``--depth-rate 5``), sent as the robot sends them (JPEG at its quality,
``compressedDepth``, ``CameraInfo``) and no odometry: the camera alone.

Each frame goes the session worker's way (``VisualWorker._add``: ``frame_of`` decodes
the messages, ``VisualMapper.add`` tracks and grows the map; the grid is made every 10
frames, as the worker saves it every 2 s), timed in process CPU time; rendering and the
robot's encoding are not timed. Figures (``--json``: one object, these keys):

- ``ate_rmse_m``: absolute trajectory error, the RMS distance of the keyframes' final
  (optimised) positions from the truth after the best rigid alignment (``se2.aligning``,
  Umeyama); ``rpe_per_m``: the mean translation error of the motion between keyframes
  about a metre of path apart, over that path's length;
- ``loop_closures`` and ``false_loop_closures``: a closure is false when its measured
  relative pose misses the truth by more than ``FALSE_LOOP`` (0.3 m or 10 degrees);
- ``tracking_lost``: frames the tracker could not place; ``tracking_relocalised``:
  frames placed by a search of every keyframe after a loss; ``tracking_restarted``: lost
  frames it started mapping again from (odometry's pose after 5 lost in a row; the tour
  sends no odometry, so relocalisation alone ends a loss here and this stays 0);
- ``frames_per_s``: frames one core could take (1 / the mean CPU a frame);
  ``cpu_per_robot``: the share of a core a robot's 5 frames/s take;
- ``grid_cell_agreement``: the derived 2D grid against the building's truth over the
  toured spaces, on cells both call known (``benchmarks.mapping.compare_with_truth``, the
  laser mapper's measure);
- ``relocalise_success``: ``--wakeups`` wake-ups at seeded free poses in the toured
  spaces against the new map's relocalisation map as publishing stores it (its
  keyframes without near-duplicates: ``keyframes.thinned``, the keyframe store's rule),
  as ``bench relocalise`` makes them (one view, then turns of 60 degrees; success within
  0.25 m and 5 degrees);
- ``peer_ate_rmse_m`` and ``peer_cpu_per_robot``: Open3D 0.20's tensor RGB-D odometry
  (hybrid photometric and geometric, frame to frame, from two guesses: standing still
  and the last motion) and its pose graph (``global_optimization``,
  Levenberg-Marquardt, with loop edges between the same frames ours closed on,
  measured by Open3D's odometry from its own estimate), on the same messages decoded
  the same way, timed the same way; its error is taken at the same frames (ours'
  keyframes).

``python manage.py bench visual-slam --seed 0 --json``; ``--laps 1`` or ``--metres 20``
shorten the tour.
"""

from __future__ import annotations

import argparse
import bisect
import itertools
import json
import math
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import cv2
import numpy as np

from benchmarks.mapping import compare_with_truth
from benchmarks.relocalise import Result, _free_poses, wake_up
from benchmarks.visual_tracking import path_length, robot_motion
from cloudnav_core.camera import CameraModel, Intrinsics, Mount
from cloudnav_core.messages import camera_info, compressed_depth
from cloudnav_core.params import RobotConfig
from cloudnav_core.se2 import Pose, aligning, compose, relative, transform
from maps.domain.demo_building import demo_building
from maps.domain.keyframes import DEPTH_RANGE, Keyframe, thinned
from maps.domain.relocalisation import KeyframeIndex, Params
from maps.domain.visual_input import depth_image, grey_image
from maps.domain.visual_mapping import VisualMapper, frame_of
from maps.domain.vocabulary import default_vocabulary
from robots.agent.hardware import compressed_image_message, encode_jpeg
from robots.agent.perception import pinhole_calibration
from robots.agent.sim.camera import Camera
from robots.agent.sim.world import demo_world

NAME = "visual-slam"
CAMERA_RATE = 5.0
"""Frames a second a robot's camera sends with depth (the simulated ``--depth-rate 5``)."""
GRID_EVERY = 10
"""Frames between grids: the session worker saves every 2 s, 10 frames at 5 frames/s."""
PIXEL_LIMIT = 640 * 480
FALSE_LOOP = (0.3, math.radians(10.0))
RPE_PATH = 1.0
"""Metres of path between the two ends of a relative pose error."""
LAP = (
    (5.0, 23.2),  # Corridor A's west end
    (12.0, 23.2),
    (17.0, 23.8),
    (19.0, 23.8),  # through the door into Atrium 1
    (19.0, 20.2),  # around the atrium, 1 m from its walls, outside its pillars
    (25.0, 20.2),
    (25.0, 26.2),
    (19.0, 26.2),
    (19.0, 23.8),
    (17.0, 23.8),  # back out and down Corridor A
    (12.0, 23.2),
    (5.0, 23.2),
)
TOURED = (3.8, 19.2, 26.0, 27.2)
"""Corridor A and Atrium 1 (x0, y0, x1, y1): the grid is compared and wake-ups are made here."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--seed", type=int, default=0, help="wall textures, noise, wake-ups")
    parser.add_argument("--laps", type=int, default=2, help="laps of the tour (52 m each)")
    parser.add_argument("--metres", type=float, default=0.0, help="stop after this far (0: all)")
    parser.add_argument("--step", type=float, default=0.1, help="metres between frames")
    parser.add_argument("--turn", type=float, default=10.0, help="degrees between frames")
    parser.add_argument("--wakeups", type=int, default=50, help="wake-ups on the new map")
    parser.add_argument(
        "--peer-scale", type=float, default=0.5,
        help="Open3D's frames scaled by this (1: full size, 4 to 5 times its CPU)",
    )  # fmt: skip
    parser.add_argument("--json", action="store_true", help="print one JSON object")


def run(options: dict[str, Any]) -> None:
    result = measure(options)
    print(json.dumps(result) if options["json"] else report(result))


def measure(options: dict[str, Any]) -> dict[str, Any]:
    """Every figure of one seeded tour (the keys ``--json`` prints)."""
    seed = options["seed"]
    poses = tour(options["laps"], options["step"], math.radians(options["turn"]))
    if options["metres"] > 0:
        poses = shortened(poses, options["metres"])
    messages = robot_messages(poses, seed)
    ours = run_mapper(poses[0], messages)
    keyframe_truth = [poses[i] for i in ours.keyframe_frames]
    peer = run_peer(poses[0], messages, ours.loop_frames, options["peer_scale"])
    grid, origin = ours.mapper.grid()
    building = demo_building()
    agreement, _ = compare_with_truth(grid, origin, building.world, building.world_origin, TOURED)
    frames = len(poses)
    published = thinned(ours.mapper.keyframes())
    result = {
        "seed": seed,
        "tour_m": round(path_length(poses), 1),
        "frames": frames,
        "ate_rmse_m": round(ate_rmse(ours.mapper.path, keyframe_truth), 4),
        "rpe_per_m": round(rpe_per_m(ours.mapper.path, keyframe_truth), 4),
        "loop_closures": ours.mapper.stats.loop_closures,
        "false_loop_closures": false_loops(ours, poses),
        "tracking_lost": ours.mapper.stats.lost,
        "tracking_relocalised": ours.mapper.stats.relocalised,
        "tracking_restarted": ours.mapper.stats.restarted,
        "frames_per_s": round(frames / ours.cpu_s, 1),
        "cpu_per_robot": round(ours.cpu_s / frames * CAMERA_RATE, 3),
        "grid_cell_agreement": round(agreement, 4),
        "relocalise_success": relocalise_success(
            published, ours.mapper.vocabulary.size, seed, options["wakeups"]
        ),
        "peer_ate_rmse_m": round(
            ate_rmse([peer.poses[i] for i in ours.keyframe_frames], keyframe_truth), 4
        ),
        "peer_cpu_per_robot": round(peer.cpu_s / frames * CAMERA_RATE, 3),
    }
    print(
        f"{len(ours.keyframe_frames)} keyframes, {len(published)} kept by publishing; "
        f"Open3D's odometry failed on {peer.failed} "
        f"frames, {peer.loops} of {len(ours.loop_frames)} loop edges measured",
        file=sys.stderr,
    )
    return result


# --- the tour ---------------------------------------------------------------------------


def tour(laps: int = 2, step: float = 0.1, turn: float = math.radians(10.0)) -> list[Pose]:
    """``laps`` of ``LAP``: straight legs in ``step`` metres, turns on the spot at each
    waypoint in at most ``turn`` radians, a half turn at the end of each lap."""
    first = LAP[0]
    poses: list[Pose] = [(first[0], first[1], 0.0)]
    for waypoint in [*LAP[1:], *[p for _ in range(laps - 1) for p in LAP[1:]]]:
        _face(poses, math.atan2(waypoint[1] - poses[-1][1], waypoint[0] - poses[-1][0]), turn)
        _go(poses, waypoint, step)
        if waypoint == first:
            _face(poses, poses[-1][2] + math.pi, turn)
    return poses


def _face(poses: list[Pose], heading: float, turn: float) -> None:
    x, y, yaw = poses[-1]
    change = math.remainder(heading - yaw, math.tau)
    steps = math.ceil(abs(change) / turn - 1e-9)
    poses.extend(
        (x, y, math.remainder(yaw + change * k / steps, math.tau)) for k in range(1, steps + 1)
    )


def _go(poses: list[Pose], to: tuple[float, float], step: float) -> None:
    x, y, yaw = poses[-1]
    steps = max(1, math.ceil(math.dist((x, y), to) / step - 1e-9))
    poses.extend(
        (x + (to[0] - x) * k / steps, y + (to[1] - y) * k / steps, yaw) for k in range(1, steps + 1)
    )


def shortened(poses: list[Pose], metres: float) -> list[Pose]:
    """The first poses of ``poses`` up to ``metres`` of path."""
    lengths = list(
        itertools.accumulate(math.dist(a[:2], b[:2]) for a, b in itertools.pairwise(poses))
    )
    return poses[: bisect.bisect_right(lengths, metres) + 1]


# --- the robot's messages ------------------------------------------------------------------

Messages = tuple[Any, Any, Any]
"""A frame as the robot sends it: its image, depth and camera_info messages."""


def robot_messages(poses: Sequence[Pose], seed: int) -> list[Messages]:
    """The simulated camera's frames at ``poses``, encoded as the robot sends them (one
    frame every 1 / ``CAMERA_RATE`` simulated seconds)."""
    model = CameraModel()
    camera = Camera(demo_world(seed=seed), model, seed=seed)
    calibration = pinhole_calibration(model)
    quality = RobotConfig().jpeg_quality
    messages = []
    for index, pose in enumerate(poses):
        image, depth = camera.capture(pose)
        assert depth is not None
        stamp = 100.0 + index / CAMERA_RATE
        messages.append(
            (
                compressed_image_message(encode_jpeg(image, quality), stamp),
                compressed_depth("camera_optical_frame", depth, stamp),
                camera_info("camera_optical_frame", calibration, stamp),
            )
        )
    return messages


# --- ours ---------------------------------------------------------------------------------


@dataclass
class Mapped:
    mapper: VisualMapper
    cpu_s: float = 0.0
    keyframe_frames: list[int] = field(default_factory=list)
    """The frame each keyframe was made from, in keyframe order."""

    @property
    def loop_frames(self) -> list[tuple[int, int, Pose]]:
        """Each loop closure as (older frame, newer frame, newer's pose in older's frame)."""
        return [
            (self.keyframe_frames[i], self.keyframe_frames[j], seen)
            for i, j, seen, _, loop in self.mapper.slam.edges
            if loop
        ]


def run_mapper(start: Pose, messages: Sequence[Messages]) -> Mapped:
    """The session worker's path for every frame, timed (decoding, tracking, the grid)."""
    mapped = Mapped(VisualMapper(default_vocabulary(), start))
    for index, (image, depth, info) in enumerate(messages):
        began = time.process_time()
        mapped.mapper.add(frame_of(image, depth, info, None, PIXEL_LIMIT))
        if index % GRID_EVERY == GRID_EVERY - 1:
            mapped.mapper.grid()
        mapped.cpu_s += time.process_time() - began
        if mapped.mapper.stats.keyframes > len(mapped.keyframe_frames):
            mapped.keyframe_frames.append(index)
    return mapped


def false_loops(mapped: Mapped, truth: Sequence[Pose]) -> int:
    """Loop closures whose measured relative pose misses the truth's by ``FALSE_LOOP``."""
    wrong = 0
    for older, newer, seen in mapped.loop_frames:
        error = relative(seen, relative(truth[older], truth[newer]))
        wrong += math.hypot(error[0], error[1]) > FALSE_LOOP[0] or abs(error[2]) > FALSE_LOOP[1]
    return wrong


def relocalise_success(
    keyframes: list[Keyframe], vocabulary_size: int, seed: int, wakeups: int
) -> float:
    """The share of ``wakeups`` seeded wake-ups in the toured spaces that ``keyframes``
    (the relocalisation map publishing stores: ``thinned``) place within ``SUCCESS``
    (``bench relocalise``'s wake-up)."""
    if wakeups <= 0:
        return 0.0
    world = demo_world(seed=seed)
    index = KeyframeIndex(vocabulary_size)
    for position, keyframe in enumerate(keyframes):
        index.add(position, "", keyframe)
    result = Result(seed)
    camera = Camera(world, seed=seed + 3)
    rng = np.random.default_rng([seed, 2])
    for pose in _free_poses(world, rng, wakeups, within=TOURED):
        wake_up(index, camera, demo_building(), pose, result, Params())
    return round(result.successes / max(1, result.trials), 3)


# --- the peer: Open3D ---------------------------------------------------------------------


@dataclass
class PeerRun:
    poses: list[Pose] = field(default_factory=list)
    cpu_s: float = 0.0
    failed: int = 0
    loops: int = 0


PEER_ITERATIONS = (20, 20, 10, 5)
"""Open3D's odometry iterations per pyramid level, coarsest first: four levels, as its
three (20, 10, 5) let a 10-degree turn slip into a phantom step sideways."""
PEER_DEPTH_DIFF = 0.07
"""Metres two depths may differ and still be one point (Open3D's ``depth_outlier_trunc``)."""


class _Odometry:
    """Open3D's tensor RGB-D odometry (hybrid photometric and geometric, multi-scale) on
    frames of one camera, its convention kept: ``motion(source, target, guess)`` is the
    source camera's pose in the target camera's frame (4x4), or None when it fails."""

    def __init__(self, intrinsics: Intrinsics) -> None:
        import open3d as o3d  # here: listing the benchmarks needs no Open3D

        self.o3d = o3d
        odometry = o3d.t.pipelines.odometry
        self.camera = _tensor(intrinsics.matrix())
        self.criteria = [odometry.OdometryConvergenceCriteria(n) for n in PEER_ITERATIONS]
        self.loss = odometry.OdometryLossParams(depth_outlier_trunc=PEER_DEPTH_DIFF)

    def motion(
        self, source: Any, target: Any, guess: np.ndarray
    ) -> tuple[np.ndarray, float] | None:
        """The motion and its fitness (the share of pixels that agree)."""
        odometry = self.o3d.t.pipelines.odometry
        try:
            found = odometry.rgbd_odometry_multi_scale(
                source, target, self.camera, _tensor(guess), 1.0,
                DEPTH_RANGE[1], self.criteria, odometry.Method.Hybrid, self.loss,
            )  # fmt: skip
        except RuntimeError:  # "Singular 6x6 linear system": nothing to track on
            return None
        return found.transformation.numpy(), float(found.fitness)

    def best(self, source: Any, target: Any, guesses: Sequence[np.ndarray]) -> np.ndarray | None:
        """The motion from whichever of ``guesses`` fits the most pixels."""
        found = [m for m in (self.motion(source, target, g) for g in guesses) if m is not None]
        return max(found, key=lambda m: m[1])[0] if found else None

    def information(self, source: Any, target: Any, motion: np.ndarray) -> np.ndarray:
        """The 6x6 information matrix of ``motion`` between two frames, for the pose graph."""
        information = self.o3d.t.pipelines.odometry.compute_odometry_information_matrix(
            source.depth, target.depth, self.camera, _tensor(motion),
            PEER_DEPTH_DIFF, 1.0, DEPTH_RANGE[1],
        )  # fmt: skip
        return np.asarray(information.numpy(), np.float64)


def run_peer(
    start: Pose,
    messages: Sequence[Messages],
    loops: Sequence[tuple[int, int, Pose]],
    scale: float = 0.5,
) -> PeerRun:
    """Open3D's RGB-D odometry frame to frame, then its pose graph with loop edges
    between the frames of ``loops``, timed as ours is (decoding included); the frames
    are resized by ``scale`` after decoding (its odometry is far slower than ours).

    Each step starts from two guesses, standing still and the last step again (a turn
    goes on turning), and keeps the one more pixels agree with: from standing still
    alone Open3D misses most 10-degree turns, and the last step alone feeds one bad
    step into the next, which ran the trajectory away by hundreds of metres."""
    import open3d as o3d

    intrinsics, mount = scaled(Intrinsics(), scale), Mount()
    odometry = _Odometry(intrinsics)
    registration = o3d.pipelines.registration
    peer = PeerRun()
    graph = registration.PoseGraph()
    world = np.eye(4)  # the newest camera in the first camera's frame
    graph.nodes.append(registration.PoseGraphNode(world))
    motion = np.eye(4)  # the last step: the previous camera in the newest one's frame
    kept: dict[int, Any] = {}  # the loops' frames, for their edges
    wanted = {index for older, newer, _ in loops for index in (older, newer)}
    previous = None
    for index, (image, depth, _) in enumerate(messages):
        began = time.process_time()
        frame = _rgbd(image, depth, intrinsics)
        if previous is not None:
            found = odometry.best(previous, frame, (np.eye(4), motion))
            if found is None:
                peer.failed += 1
            motion = np.eye(4) if found is None else found
            world = world @ np.linalg.inv(motion)
            graph.nodes.append(registration.PoseGraphNode(world))
            information = odometry.information(previous, frame, motion)
            graph.edges.append(
                registration.PoseGraphEdge(index - 1, index, motion, information, uncertain=False)
            )
        previous = frame
        if index in wanted:
            kept[index] = frame
        peer.cpu_s += time.process_time() - began
    began = time.process_time()
    _add_peer_loops(graph, odometry, kept, loops, peer)
    registration.global_optimization(
        graph,
        registration.GlobalOptimizationLevenbergMarquardt(),
        registration.GlobalOptimizationConvergenceCriteria(),
        registration.GlobalOptimizationOption(
            max_correspondence_distance=PEER_DEPTH_DIFF, edge_prune_threshold=0.25,
            reference_node=0,
        ),
    )  # fmt: skip
    peer.cpu_s += time.process_time() - began
    peer.poses = [
        compose(start, robot_motion(np.asarray(node.pose), mount)) for node in graph.nodes
    ]
    return peer


def _add_peer_loops(
    graph: Any,
    odometry: _Odometry,
    kept: dict[int, Any],
    loops: Sequence[tuple[int, int, Pose]],
    peer: PeerRun,
) -> None:
    """A loop edge for each of ``loops`` Open3D's odometry measures, from its own
    estimate of the two frames' poses (uncertain: the optimiser may prune it)."""
    registration = odometry.o3d.pipelines.registration
    for older, newer, _ in loops:
        guess = np.linalg.inv(graph.nodes[newer].pose) @ graph.nodes[older].pose
        found = odometry.motion(kept[older], kept[newer], guess)
        if found is None:
            continue
        peer.loops += 1
        information = odometry.information(kept[older], kept[newer], found[0])
        graph.edges.append(
            registration.PoseGraphEdge(older, newer, found[0], information, uncertain=True)
        )


def scaled(intrinsics: Intrinsics, scale: float) -> Intrinsics:
    """The camera of images resized by ``scale`` (pixel centres kept)."""
    width, height = round(intrinsics.width * scale), round(intrinsics.height * scale)
    cx, cy = (intrinsics.cx + 0.5) * scale - 0.5, (intrinsics.cy + 0.5) * scale - 0.5
    return Intrinsics(width, height, intrinsics.fx * scale, intrinsics.fy * scale, cx, cy)


def _rgbd(image: dict[str, Any], depth: dict[str, Any], camera: Intrinsics) -> Any:
    """Open3D's (tensor) RGB-D image of a frame's messages, read by the session's own
    readers and resized to ``camera``'s size: the grey image as three equal channels
    (its odometry takes colour), depth in metres, 0 where there is no reading."""
    import open3d as o3d

    grey: Any = grey_image(image, PIXEL_LIMIT)
    metres: Any = depth_image(depth, grey.shape, PIXEL_LIMIT)
    metres = np.where(np.isfinite(metres), metres, 0.0).astype(np.float32)
    if grey.shape != (camera.height, camera.width):
        size = (camera.width, camera.height)
        grey = cv2.resize(grey, size, interpolation=cv2.INTER_AREA)
        metres = cv2.resize(metres, size, interpolation=cv2.INTER_NEAREST)
    colour = np.ascontiguousarray(np.repeat(grey[:, :, None], 3, axis=2))
    return o3d.t.geometry.RGBDImage(
        o3d.t.geometry.Image(_tensor(colour)),
        o3d.t.geometry.Image(_tensor(metres)),
    )


def _tensor(array: np.ndarray) -> Any:
    """Open3D's tensor of ``array`` (a copy, so Open3D never holds numpy's memory)."""
    import open3d as o3d

    return o3d.core.Tensor.from_numpy(np.ascontiguousarray(array).copy())


# --- errors ---------------------------------------------------------------------------------


def ate_rmse(estimate: Sequence[Pose], truth: Sequence[Pose]) -> float:
    """RMS position error of ``estimate`` after its best rigid alignment on ``truth``."""
    found = np.array([p[:2] for p in estimate], np.float64)
    true = np.array([p[:2] for p in truth], np.float64)
    if len(found) < 2:
        return 0.0
    moved = transform(aligning(found, true), found)
    return float(np.sqrt(np.mean(np.sum((moved - true) ** 2, axis=1))))


def rpe_per_m(estimate: Sequence[Pose], truth: Sequence[Pose]) -> float:
    """Mean translation error of the motion from each pose to the first one at least
    ``RPE_PATH`` metres of true path later, over that path's length."""
    travelled = [
        0.0,
        *itertools.accumulate(math.dist(a[:2], b[:2]) for a, b in itertools.pairwise(truth)),
    ]
    rates = []
    for i in range(len(truth)):
        j = bisect.bisect_left(travelled, travelled[i] + RPE_PATH)
        if j >= len(truth):
            break
        error = relative(relative(estimate[i], estimate[j]), relative(truth[i], truth[j]))
        rates.append(math.hypot(error[0], error[1]) / (travelled[j] - travelled[i]))
    return float(np.mean(rates)) if rates else 0.0


def report(result: dict[str, Any]) -> str:
    return "\n".join(f"{key:>22}: {value}" for key, value in result.items())
