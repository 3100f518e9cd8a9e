"""An AMCL-like particle filter on the laser, in the current sub-map's frame.

What it takes from AMCL (ROS 1 ``amcl``, Nav2's ``nav2_amcl``):

* **Motion**: the odometry model of a differential drive (Thrun's
  ``sample_motion_model_odometry``, AMCL's ``diff`` model, ``alpha1..alpha4``). As in
  AMCL, the noise is drawn once per filter update for the whole motion since the last
  one, so the spread does not depend on how often odometry arrives; between updates the
  particles follow odometry without noise, so ``pose()`` is always current.
* **Updates** happen only after ``update_min_d`` metres or ``update_min_a`` radians of
  motion since the last one; ``update`` says whether it ran.
* **Measurement**: the likelihood field (``robots.agent.likelihood``), 60 beams a scan,
  by default as AMCL's ``likelihood_field_prob`` (a product over beams); AMCL's
  ``likelihood_field`` (a sum of cubes) is the other choice of ``laser_model``.
* **Resampling**: KLD-sampling (bins 0.5 m x 0.5 m x 10 degrees, ``kld_err``,
  ``kld_z``), done only when the effective sample size falls below
  ``resample_threshold`` of the particle count (AMCL's selective resampling).

Where it departs from AMCL: the estimate is the weighted mean of all particles (AMCL
reports the heaviest cluster's mean), so a cloud split between two hypotheses reports a
pose in between, with a covariance that says so; KLD-sampling with every particle in
one bin keeps ``min_particles`` (AMCL jumps to ``max_particles`` there); beams that end
beyond the open edge of a sub-map's window are left out rather than scored as misses
(see ``robots.agent.likelihood``); and there is no recovery by random particles
(augmented MCL): a global start that gathers on a look-alike pose stays there, which a
tag reading corrects with ``reset``.

Frames: poses are ``(x, y, yaw)`` in the map frame of the grid. Sub-maps of a building
share one frame (the demo's do), so ``set_map`` keeps the particles by default.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import fields, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from cloudnav_core.params import BeamModel, FilterParams
from cloudnav_core.se2 import Pose, compose, relative, wrap
from robots.agent.likelihood import Grid, LikelihoodField, beams_of

Floats = NDArray[np.float64]

KLD_BIN = (0.5, 0.5, math.radians(10))
"""AMCL's histogram bin for KLD-sampling: metres, metres, radians."""
_STILL = 0.01
"""Metres: below this the motion's heading (rot1) is meaningless and taken as 0 (AMCL)."""
_NO_POSES: Floats = np.empty((0, 3))
_NO_POSES.flags.writeable = False


class NotLocalisedError(RuntimeError):
    """The filter holds no particles: a map was swapped without a shared frame."""


def params_from(base: FilterParams, overrides: Mapping[str, Any]) -> FilterParams:
    """``base`` with ``overrides``, keyword arguments of ``FilterParams`` names where laser
    keys (``z_hit``, ``z_rand``, ``sigma_hit``, ``max_distance``, ``max_beams``,
    ``laser_model``, ``laser_pose``) go to its ``BeamModel``.

    Raises TypeError for an unknown name, ValueError for values ``FilterParams`` or
    ``BeamModel`` refuse.
    """
    beam_names = {f.name for f in fields(BeamModel)}
    beam_args = {k: v for k, v in overrides.items() if k in beam_names}
    filter_args = {k: v for k, v in overrides.items() if k not in beam_names}
    return replace(base, **filter_args, beams=replace(base.beams, **beam_args))


def odometry_delta(before: Pose, after: Pose) -> Pose:
    """The motion from odometry pose ``before`` to ``after`` in the robot frame at
    ``before``: ``(forward, left, turn)``, what ``predict`` takes."""
    return relative(before, after)


class ParticleFilter:
    """Monte Carlo localisation on ``grid`` (the current sub-map: int8, row 0 = bottom,
    cell (0, 0)'s corner at ``origin``, ``resolution`` m per cell).

    It starts with no particles: call ``reset`` (from a tag) or ``reset_uniform``. Its
    settings are ``params`` (the defaults of ``FilterParams`` without) with ``overrides``
    (see ``params_from``), which also says what is raised for bad ones.
    """

    def __init__(
        self,
        grid: Grid,
        resolution: float,
        origin: tuple[float, float, float],
        params: FilterParams | None = None,
        *,
        seed: int | None = None,
        **overrides: Any,
    ) -> None:
        self.params = params_from(params or FilterParams(), overrides)
        self.rng = np.random.default_rng(seed)
        self.field = LikelihoodField(grid, resolution, origin, self.params.beams)
        self._anchor: Floats = _NO_POSES  # particles at the last update
        self._poses: Floats = _NO_POSES  # _anchor moved by _travel, without noise
        self._weights: Floats = np.empty(0)
        self._travel: Pose = (0.0, 0.0, 0.0)  # odometry since the last update, frame there

    # --- initialisation ----------------------------------------------------------------

    def reset(self, pose: Pose, covariance: NDArray[np.float64]) -> None:
        """Draw ``particles`` poses from a Gaussian at ``pose`` with the 3x3 ``covariance``
        (x, y, yaw): an initial pose from a tag or an operator.

        Raises ValueError when ``covariance`` is not 3x3.
        """
        covariance = np.asarray(covariance, np.float64)
        if covariance.shape != (3, 3):
            raise ValueError("the covariance is 3x3 over x, y, yaw")
        mean = np.asarray(pose, np.float64)
        count = self.params.particles
        drawn = self.rng.multivariate_normal(mean, covariance, count, method="eigh")
        drawn[:, 2] = wrap(drawn[:, 2])
        self._start(drawn)

    def reset_uniform(self) -> None:
        """Spread ``max_particles`` poses over the map's free cells with any heading
        (global localisation). Raises ValueError when the map has no free cell."""
        self._start(self.field.free_poses(self.params.max_particles, self.rng))

    def _start(self, poses: Floats) -> None:
        self._anchor, self._poses = poses, poses.copy()
        self._weights = np.full(len(poses), 1.0 / len(poses))
        self._travel = (0.0, 0.0, 0.0)

    # --- motion ------------------------------------------------------------------------

    def predict(self, odom_delta: Pose) -> None:
        """Move every particle by ``odom_delta`` = ``(forward, left, turn)``, the odometry
        motion in the robot frame at its start (``odometry_delta`` computes it from two
        odometry poses). The noise of the motion model is applied at the next update."""
        self._travel = compose(self._travel, odom_delta)
        if len(self._anchor):
            self._poses = _moved(self._anchor, *_odometry_steps(self._travel))

    def _moved_enough(self) -> bool:
        forward, left, turn = self._travel
        p = self.params
        return math.hypot(forward, left) >= p.update_min_d or abs(turn) >= p.update_min_a

    def _sample_motion(self) -> Floats:
        """The anchors moved by ``_travel`` with AMCL's diff-drive noise, one draw each."""
        rot1, trans, rot2 = _odometry_steps(self._travel)
        # Backing up is not turning round: measure turns against the nearer of the two
        # directions of travel, as AMCL does.
        rot1_noise = min(abs(rot1), abs(wrap(rot1 - math.pi)))
        rot2_noise = min(abs(rot2), abs(wrap(rot2 - math.pi)))
        p, n = self.params, len(self._anchor)
        sigma_rot1 = math.sqrt(p.alpha1 * rot1_noise**2 + p.alpha2 * trans**2)
        sigma_trans = math.sqrt(p.alpha3 * trans**2 + p.alpha4 * (rot1_noise**2 + rot2_noise**2))
        sigma_rot2 = math.sqrt(p.alpha1 * rot2_noise**2 + p.alpha2 * trans**2)
        return _moved(
            self._anchor,
            rot1 - self.rng.normal(0.0, sigma_rot1, n),
            trans - self.rng.normal(0.0, sigma_trans, n),
            rot2 - self.rng.normal(0.0, sigma_rot2, n),
        )

    # --- measurement -------------------------------------------------------------------

    def update(self, scan: Mapping[str, Any]) -> bool:
        """Run one filter update with ``scan`` (a ``sensor_msgs/LaserScan`` dict) if the
        robot moved ``update_min_d`` or turned ``update_min_a`` since the last one: motion
        noise, weighting, and resampling when the weights have degenerated.

        Returns whether it ran (False too without particles); a scan without a usable
        beam still applies the motion. Raises KeyError for a scan missing a field.
        """
        if not len(self._anchor) or not self._moved_enough():
            return False
        beams = beams_of(scan, self.params.beams)
        self._poses = self._sample_motion()
        if beams.count:
            self._weigh(self.field.log_likelihood(self._poses, beams, self._weights))
            if self._effective_size() < self.params.resample_threshold * len(self._poses):
                self._resample()
        self._anchor, self._travel = self._poses.copy(), (0.0, 0.0, 0.0)
        return True

    def _weigh(self, log_likelihood: Floats) -> None:
        """Multiply the weights by the likelihood, in logs so that no product underflows."""
        with np.errstate(divide="ignore"):  # a zero weight stays zero
            log_w = np.log(self._weights) + log_likelihood
        weighted = np.exp(log_w - log_w.max())
        self._weights = weighted / weighted.sum()

    def _effective_size(self) -> float:
        return float(1.0 / np.square(self._weights).sum())

    # --- resampling --------------------------------------------------------------------

    def _resample(self) -> None:
        """KLD-sampling: draw up to ``max_particles`` from the weights and keep the
        shortest prefix that the KLD bound allows."""
        p = self.params
        drawn = self._poses[self._draw(p.max_particles)]
        keep = kld_count(drawn, p.min_particles, p.max_particles, p.kld_err, p.kld_z)
        self._poses = drawn[:keep]
        self._weights = np.full(keep, 1.0 / keep)

    def _draw(self, count: int) -> NDArray[np.intp]:
        """Indices of ``count`` independent draws by weight (a prefix of i.i.d. draws is
        itself a fair sample, which KLD-sampling needs)."""
        cumulative = np.cumsum(self._weights)
        picks = np.searchsorted(cumulative, self.rng.random(count) * cumulative[-1])
        drawn: NDArray[np.intp] = np.minimum(picks, len(self._weights) - 1)
        return drawn

    # --- estimate ----------------------------------------------------------------------

    def pose(self) -> Pose:
        """Weighted mean pose (circular mean for yaw). Raises NotLocalisedError."""
        poses, w = self._current()
        yaw = math.atan2(float(w @ np.sin(poses[:, 2])), float(w @ np.cos(poses[:, 2])))
        return float(w @ poses[:, 0]), float(w @ poses[:, 1]), yaw

    def covariance(self) -> NDArray[np.float64]:
        """3x3 weighted covariance over (x, y, yaw), yaw deviations taken about the
        circular mean. Raises NotLocalisedError."""
        poses, w = self._current()
        mean = self.pose()
        deviation = poses - np.asarray(mean)
        deviation[:, 2] = wrap(deviation[:, 2])
        return np.asarray((deviation * w[:, None]).T @ deviation, np.float64)

    def particles(self) -> NDArray[np.float64]:
        """A copy of the particles' poses, N x 3 (x, y, yaw), for drawing."""
        return self._poses.copy()

    def weights(self) -> NDArray[np.float64]:
        """A copy of the particles' normalised weights, in the order of ``particles()``."""
        return self._weights.copy()

    def _current(self) -> tuple[Floats, Floats]:
        if not len(self._poses):
            raise NotLocalisedError("the filter has no particles: reset it first")
        return self._poses, self._weights

    # --- maps --------------------------------------------------------------------------

    def set_map(
        self,
        grid: Grid,
        resolution: float,
        origin: tuple[float, float, float],
        *,
        shared_frame: bool = True,
    ) -> None:
        """Localise on another map from now on, its likelihood field computed once here.

        With ``shared_frame`` (the new map's frame is the old one's, as for the sub-maps of
        one building) the particles stay where they are; otherwise they are dropped, and
        the filter needs a ``reset`` before it estimates again.
        """
        self.field = LikelihoodField(grid, resolution, origin, self.params.beams)
        if not shared_frame:
            self._anchor, self._poses, self._weights = _NO_POSES, _NO_POSES, np.empty(0)


def kld_count(
    drawn: Floats, min_particles: int, max_particles: int, kld_err: float, kld_z: float
) -> int:
    """How many of ``drawn`` (i.i.d. draws, in order) KLD-sampling keeps: the first ``n``
    at which ``n`` exceeds the bound for the ``k`` histogram bins the first ``n`` fill,
    clamped to ``[min_particles, max_particles]`` and to ``len(drawn)``."""
    keys = _bin_keys(drawn)
    _, first = np.unique(keys, return_index=True)
    new_bin = np.zeros(len(drawn), np.int64)
    new_bin[first] = 1
    bins = np.cumsum(new_bin)
    needed = np.clip(_kld_bound(bins, kld_err, kld_z), min_particles, max_particles)
    enough = np.flatnonzero(np.arange(1, len(drawn) + 1) >= needed)
    return int(enough[0] + 1) if enough.size else len(drawn)


def _kld_bound(k: NDArray[np.int64], kld_err: float, kld_z: float) -> Floats:
    """Fox's bound (Wilson-Hilferty) on the sample size for ``k`` occupied bins, as AMCL
    computes it (``kld_z`` used as the normal quantile); 0 for a single bin."""
    dof = np.maximum(k - 1, 1).astype(np.float64)
    b = 2.0 / (9.0 * dof)
    bound = dof / (2.0 * kld_err) * (1.0 - b + np.sqrt(b) * kld_z) ** 3
    return np.where(k > 1, np.ceil(bound), 0.0)


def _bin_keys(poses: Floats) -> NDArray[np.int64]:
    """One integer per KLD bin (21 bits per axis; wraps only beyond 500 km)."""
    cells = np.floor(poses / np.asarray(KLD_BIN)).astype(np.int64) & ((1 << 21) - 1)
    return np.asarray((cells[:, 0] << 42) | (cells[:, 1] << 21) | cells[:, 2], np.int64)


def _odometry_steps(travel: Pose) -> tuple[float, float, float]:
    """``(rot1, trans, rot2)``: turn toward the end point, drive, turn to the end heading."""
    forward, left, turn = travel
    trans = math.hypot(forward, left)
    rot1 = math.atan2(left, forward) if trans >= _STILL else 0.0
    return rot1, trans, wrap(turn - rot1)


def _moved(
    poses: Floats, rot1: float | Floats, trans: float | Floats, rot2: float | Floats
) -> Floats:
    """``poses`` after turning ``rot1``, driving ``trans`` and turning ``rot2``."""
    heading = poses[:, 2] + rot1
    moved = np.empty_like(poses)
    moved[:, 0] = poses[:, 0] + trans * np.cos(heading)
    moved[:, 1] = poses[:, 1] + trans * np.sin(heading)
    moved[:, 2] = wrap(heading + rot2)
    return moved
