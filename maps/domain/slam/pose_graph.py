"""The pose graph's optimisation (``optimise_graph``): poses that best agree with relative
pose edges, some of them loop closures with a Huber-robust noise model.

The optimiser is GTSAM's (``gtsam`` on PyPI, Georgia Tech, maintained and released through
2026): Pose2 factors, robust noise models and sparse solvers are exactly what a 2D pose
graph needs, and writing them again would be slower and less tried.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from cloudnav_core.se2 import Pose


def optimise_graph(
    poses: Sequence[Pose], edges: Sequence[tuple[int, int, Pose, tuple[float, float, float], bool]]
) -> list[Pose]:
    """Poses that best agree with ``edges`` ``(i, j, pose of j in i's frame, sigmas,
    robust)``, the first pose held fixed; by GTSAM's Levenberg-Marquardt."""
    import gtsam

    graph = gtsam.NonlinearFactorGraph()
    values = gtsam.Values()
    fixed = gtsam.noiseModel.Diagonal.Sigmas(np.array([1e-4, 1e-4, 1e-5]))
    graph.add(gtsam.PriorFactorPose2(0, gtsam.Pose2(*poses[0]), fixed))
    for index, pose in enumerate(poses):
        values.insert(index, gtsam.Pose2(*pose))
    for i, j, relative, sigmas, robust in edges:
        noise: Any = gtsam.noiseModel.Diagonal.Sigmas(np.array(sigmas))
        if robust:
            huber = gtsam.noiseModel.mEstimator.Huber.Create(1.345)
            noise = gtsam.noiseModel.Robust.Create(huber, noise)
        graph.add(gtsam.BetweenFactorPose2(i, j, gtsam.Pose2(*relative), noise))
    result = gtsam.LevenbergMarquardtOptimizer(graph, values).optimize()
    out: list[Pose] = []
    for index in range(len(poses)):
        found = result.atPose2(index)
        out.append((float(found.x()), float(found.y()), float(found.theta())))
    return out
