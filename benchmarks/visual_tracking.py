"""Visual tracking of an RGB-D camera: features with depth against OpenCV's dense RGB-D odometry.

Both trackers see the same frames, rendered by the simulator (``Camera.capture``: grey
image and registered depth) along a tour with known poses: down Corridor A, a turn on
the spot, back, and a turn to face the start again (``corridor_tour``). Loop closure is
off, so the figures are the trackers' own:

- ``step_error_m`` / ``step_error_deg``: mean error of each frame's motion (p95 too);
- ``drift_per_m``: position error at the end over the path's length;
- ``cpu_ms_per_frame``: process CPU time per frame, rendering excluded;
- ``failed``: frames the tracker could not place (the dense one keeps the last motion).

The features tracker is ``maps.domain.visual_slam``'s; the dense one OpenCV 5's
``cv2.Odometry`` (``OdometryType_RGB_DEPTH``, frame to frame, its 6-DoF motion put in
the plane).
"""

from __future__ import annotations

import argparse
import itertools
import json
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import cv2
import numpy as np

from cloudnav_core.camera import Intrinsics, Mount
from cloudnav_core.se2 import Pose, compose, inverse, relative
from maps.domain.keyframes import DEPTH_RANGE, Depth, Image
from maps.domain.visual_slam import State, VisualSlam, VisualSlamParams
from maps.domain.vocabulary import default_vocabulary
from robots.agent.sim.camera import Camera
from robots.agent.sim.world import demo_world

NAME = "visual-tracking"
START: Pose = (5.0, 23.0, 0.0)
"""Corridor A's west end, looking east along it."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--seed", type=int, default=1, help="wall textures and sensor noise")
    parser.add_argument("--length", type=float, default=8.0, help="metres down the corridor")
    parser.add_argument("--step", type=float, default=0.05, help="metres between frames")
    parser.add_argument("--turn", type=float, default=5.0, help="degrees between frames")
    parser.add_argument("--json", action="store_true", help="print one JSON object")


def run(options: dict[str, Any]) -> None:
    poses = corridor_tour(options["length"], options["step"], math.radians(options["turn"]))
    frames = rendered(poses, options["seed"])
    result = {
        "seed": options["seed"],
        "frames": len(poses),
        "path_m": round(path_length(poses), 2),
        "features": measure(poses, frames, features_tracker()).summary(),
        "dense": measure(poses, frames, dense_tracker()).summary(),
    }
    print(json.dumps(result) if options["json"] else json.dumps(result, indent=2))


def corridor_tour(
    length: float = 8.0, step: float = 0.05, turn: float = math.radians(5.0)
) -> list[Pose]:
    """Down Corridor A from ``START`` for ``length`` metres, a half turn on the spot, back,
    and another half turn: the last pose is the first."""
    ahead = [compose(START, (step * i, 0.0, 0.0)) for i in range(round(length / step) + 1)]
    tour = ahead + _spin(ahead[-1], turn)
    back = [compose(tour[-1], (step * i, 0.0, 0.0)) for i in range(1, len(ahead))]
    return tour + back + _spin(back[-1], turn)


def _spin(pose: Pose, turn: float) -> list[Pose]:
    return [compose(pose, (0.0, 0.0, turn * k)) for k in range(1, round(math.pi / turn) + 1)]


def path_length(poses: list[Pose]) -> float:
    return sum(math.dist(a[:2], b[:2]) for a, b in itertools.pairwise(poses))


def rendered(poses: list[Pose], seed: int) -> list[tuple[Image, Depth]]:
    """The simulator's grey image and depth at each pose."""
    camera = Camera(demo_world(seed=seed), seed=seed)
    frames = []
    for pose in poses:
        image, depth = camera.capture(pose)
        assert depth is not None
        frames.append((image, depth))
    return frames


Tracker = Callable[[Image, Depth], Pose | None]
"""Places one frame (None when it cannot), poses relative to the first frame's."""


def features_tracker(params: VisualSlamParams | None = None) -> Tracker:
    """The visual SLAM's tracker, loop closure off."""
    slam = VisualSlam(
        default_vocabulary(), START, params=params or VisualSlamParams(loop_candidates=0)
    )

    def track(image: Image, depth: Depth) -> Pose | None:
        tracked = slam.track(image, depth)
        return None if tracked.state is State.LOST else relative(START, tracked.pose)

    return track


def dense_tracker(intrinsics: Intrinsics | None = None, mount: Mount | None = None) -> Tracker:
    """OpenCV's dense RGB-D odometry, frame to frame, in the plane."""
    intrinsics, mount = intrinsics or Intrinsics(), mount or Mount()
    settings = cv2.OdometrySettings()
    settings.setCameraMatrix(intrinsics.matrix().astype(np.float32))
    settings.setMinDepth(DEPTH_RANGE[0])
    settings.setMaxDepth(DEPTH_RANGE[1])
    odometry = cv2.Odometry(cv2.OdometryType_RGB_DEPTH, settings, cv2.OdometryAlgoType_COMMON)
    state: dict[str, Any] = {"previous": None, "pose": (0.0, 0.0, 0.0)}

    def track(image: Image, depth: Depth) -> Pose | None:
        # Readings past its maximum depth upset OpenCV's odometry (motions a thousandth of
        # the truth): give it the range the features trust, as its settings say.
        trusted = (depth >= DEPTH_RANGE[0]) & (depth <= DEPTH_RANGE[1])
        metres = np.where(trusted, depth, 0.0).astype(np.float32)
        frame = cv2.OdometryFrame(metres, image)
        odometry.prepareFrame(frame)
        previous, state["previous"] = state["previous"], frame
        if previous is None:
            return state["pose"]  # type: ignore[no-any-return]
        ok, rt = odometry.compute(previous, frame)
        if not ok:
            return None
        state["pose"] = compose(
            state["pose"], robot_motion(np.linalg.inv(rt).astype(np.float64), mount)
        )
        return state["pose"]  # type: ignore[no-any-return]

    return track


def robot_motion(camera: np.typing.NDArray[np.float64], mount: Mount) -> Pose:
    """The robot's planar motion from its camera's (4x4, the new optical frame in the old)."""
    forward, left = float(camera[2, 3]), -float(camera[0, 3])
    turn = math.atan2(-float(camera[0, 2]), float(camera[2, 2]))
    offset = (mount.forward, 0.0, 0.0)
    return compose(compose(offset, (forward, left, turn)), inverse(offset))


@dataclass
class Measured:
    steps_m: list[float] = field(default_factory=list)
    steps_deg: list[float] = field(default_factory=list)
    cpu_s: list[float] = field(default_factory=list)
    failed: int = 0
    final_error_m: float = 0.0
    path_m: float = 0.0

    def summary(self) -> dict[str, Any]:
        return {
            "step_error_m": round(float(np.mean(self.steps_m)), 4),
            "step_error_m_p95": round(float(np.percentile(self.steps_m, 95)), 4),
            "step_error_deg": round(float(np.mean(self.steps_deg)), 3),
            "step_error_deg_p95": round(float(np.percentile(self.steps_deg, 95)), 3),
            "final_error_m": round(self.final_error_m, 3),
            "drift_per_m": round(self.final_error_m / max(self.path_m, 1e-9), 4),
            "cpu_ms_per_frame": round(1000 * float(np.mean(self.cpu_s)), 1),
            "failed": self.failed,
        }


def measure(poses: list[Pose], frames: list[tuple[Image, Depth]], tracker: Tracker) -> Measured:
    """Run ``tracker`` over ``frames`` and compare its poses with the truth ``poses``."""
    measured = Measured(path_m=path_length(poses))
    truth = [relative(poses[0], p) for p in poses]
    last: Pose = (0.0, 0.0, 0.0)
    for index, (image, depth) in enumerate(frames):
        started = time.process_time()
        found = tracker(image, depth)
        measured.cpu_s.append(time.process_time() - started)
        if found is None:
            measured.failed += 1
            found = last
        if index:
            error = relative(relative(last, found), relative(truth[index - 1], truth[index]))
            measured.steps_m.append(math.hypot(error[0], error[1]))
            measured.steps_deg.append(abs(math.degrees(error[2])))
        last = found
    measured.final_error_m = math.dist(last[:2], truth[-1][:2])
    return measured
