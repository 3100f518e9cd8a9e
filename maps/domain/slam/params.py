"""The tuning of 2D SLAM (``SlamParams``): matching, keyframes, loop closure, occupancy and
the pose graph's noise, shared by every module of ``maps.domain.slam``."""

from __future__ import annotations

import math
from dataclasses import dataclass

from cloudnav_core.grid import FREE_THRESH, OCCUPIED_THRESH


@dataclass(frozen=True)
class SlamParams:
    """Tuning of the mapper; the defaults suit an LDS-01-class laser indoors."""

    resolution: float = 0.05
    beams_used: int = 120  # beams matched per scan (evenly taken)
    usable_range: float = 7.5  # metres: farther returns are not used
    free_range: float = 4.0  # metres marked free along a beam with no return
    max_extent: float = 50.0  # metres from the start (in x and in y) a session may map
    keyframe_distance: float = 0.25
    keyframe_angle: float = math.radians(12)
    match_every: float = 0.1  # metres (or radians / 4) moved before a scan is matched again
    window_xy: float = 0.15  # metres searched either side of the prediction
    window_yaw: float = math.radians(5)
    sigma: float = 0.05  # metres: the likelihood field's Gaussian
    local_keyframes: int = 40  # recent keyframes the matcher's field is built from
    local_extent: float = 9.0  # metres either side of the robot the field covers
    min_beams: int = 40  # scans with fewer good beams are not matched
    loop_radius: float = 2.5
    loop_min_gap: int = 25  # keyframes between a keyframe and a loop closure partner
    loop_window_xy: float = 0.6
    loop_window_yaw: float = math.radians(15)
    loop_min_score: float = 0.55  # mean likelihood of the beams at the best match
    loop_every: int = 3  # keyframes between loop closure attempts
    log_hit: float = 0.9
    log_miss: float = -0.4
    log_clamp: float = 5.0
    occupied_log_odds: float = math.log(OCCUPIED_THRESH / (1 - OCCUPIED_THRESH))
    free_log_odds: float = math.log(FREE_THRESH / (1 - FREE_THRESH))
    odom_sigma: tuple[float, float, float] = (0.05, 0.05, math.radians(3))
    match_sigma: tuple[float, float, float] = (0.02, 0.02, math.radians(1))
    loop_sigma: tuple[float, float, float] = (0.05, 0.05, math.radians(2))
