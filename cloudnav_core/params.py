"""A robot's parameters: its body, its rates, and the settings of its particle filter,
global planner and local controller. Every default is given, and explained, here only.

``RobotConfig`` holds them all; its parts are frozen dataclasses, so a variant is made
with keywords (``RobotConfig(camera_rate=0)``) or ``dataclasses.replace``. The defaults
describe the simulated robot, a TurtleBot-class base with an LDS-01-class laser; the
README's "Robot parameters" table lists them (a test keeps the two in step).

Rates are in hertz of the robot's own clock (the simulated clock for simulated robots),
lengths in metres, angles in radians.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal, get_args

LaserModel = Literal["likelihood_field_prob", "likelihood_field"]
LocalPlanner = Literal["dwa", "teb"]
"""The local planners: the dynamic window approach, the timed elastic band."""
Sensors = Literal["laser", "rgbd"]
"""What the robot senses obstacles with: a 2D laser, or an RGB-D camera alone (its scan
made from depth)."""
"""AMCL's ``laser_model_type`` values that the particle filter implements."""


@dataclass(frozen=True)
class BodyLimits:
    """What the base can do: the simulated body obeys these, and the controller plans
    within them."""

    max_linear: float = 0.5
    """m/s, forwards and backwards."""
    max_angular: float = 1.5
    """rad/s."""
    linear_accel: float = 1.0
    """m/s^2, speeding up and braking."""
    angular_accel: float = 4.0
    """rad/s^2."""
    radius: float = 0.18
    """m: the footprint's circumscribed circle."""


@dataclass(frozen=True)
class BeamModel:
    """AMCL's laser parameters (ROS 1 defaults, except 60 beams as in Nav2).

    Raises ValueError for an unknown ``laser_model``, ``max_beams`` < 1 or a
    ``sigma_hit`` that is not positive.
    """

    z_hit: float = 0.95
    z_rand: float = 0.05
    sigma_hit: float = 0.2
    """m."""
    max_distance: float = 2.0
    """m: AMCL's ``laser_likelihood_max_dist``."""
    max_beams: int = 60
    laser_model: LaserModel = "likelihood_field_prob"
    laser_pose: tuple[float, float, float] = (0.0, 0.0, 0.0)
    """The laser's pose in the robot frame."""

    def __post_init__(self) -> None:
        if self.laser_model not in get_args(LaserModel):
            raise ValueError(f"unknown laser_model {self.laser_model!r}")
        if self.max_beams < 1 or self.sigma_hit <= 0:
            raise ValueError("a beam model needs max_beams >= 1 and sigma_hit > 0")


@dataclass(frozen=True)
class FilterParams:
    """The particle filter's settings; the names are AMCL's.

    ``particles`` is how many a reset from a pose draws; a uniform (global) reset draws
    ``max_particles``; resampling keeps the count within ``[min_particles,
    max_particles]``. Raises ValueError unless ``0 < min_particles <= particles <=
    max_particles``.
    """

    particles: int = 500
    min_particles: int = 100
    max_particles: int = 5000
    alpha1: float = 0.2
    """Rotation noise from rotation."""
    alpha2: float = 0.2
    """Rotation noise from translation."""
    alpha3: float = 0.2
    """Translation noise from translation."""
    alpha4: float = 0.2
    """Translation noise from rotation."""
    update_min_d: float = 0.2
    """m of motion before a filter update."""
    update_min_a: float = 0.5
    """rad of turn before a filter update."""
    kld_err: float = 0.01
    kld_z: float = 0.99
    resample_threshold: float = 0.5
    """Resample when the effective sample size falls below this share of the count."""
    beams: BeamModel = field(default_factory=BeamModel)

    def __post_init__(self) -> None:
        if not 0 < self.min_particles <= self.particles <= self.max_particles:
            raise ValueError("particle counts must satisfy 0 < min <= particles <= max")


@dataclass(frozen=True)
class PlannerConfig:
    """The global planner's costmap (``maps.domain.planning.inflate``): cells nearer an
    obstacle than the robot's radius plus ``margin`` are blocked, and paths pay to pass
    within ``gradient`` metres beyond that."""

    margin: float = 0.07
    """m added to the body's radius, for the planner only."""
    gradient: float = 0.35
    """m beyond the inflated radius over which paths pay to pass near walls."""
    gradient_weight: float = 2.0
    """Cost per metre of path at the inflated radius (falling to 0 across ``gradient``)."""


@dataclass(frozen=True)
class ControllerConfig:
    """The local controller's tuning: the dynamic window approach's, and the path
    following both local planners share (lookahead, tolerances, turning on the spot)."""

    safety: float = 0.04
    """m of clearance a trajectory keeps beyond the body's radius."""
    dynamic_obstacle_dist: float = 0.15
    """m of clearance a trajectory keeps from returns that move, beyond ``safety``, each
    predicted at constant velocity to the time the trajectory gets there (as TEB's
    ``teb.dynamic_obstacle_dist``: people may turn)."""
    back_off: float = 0.15
    """m/s: the speed the robot backs away at when something moving would run into it
    where it stands and no way forward is clear."""
    horizon: float = 1.6
    """s each sampled trajectory is simulated for."""
    linear_samples: int = 9
    angular_samples: int = 25
    lookahead: float = 0.8
    """m along the path to the point the controller steers for."""
    xy_tolerance: float = 0.08
    """m from a target that counts as there."""
    yaw_tolerance: float = 0.08
    """rad from a target's heading that counts as facing it."""
    turn_in_place: float = 0.9
    """rad off the path's direction beyond which the robot turns on the spot first."""


@dataclass(frozen=True)
class TebConfig:
    """The timed elastic band's tuning (``robots.agent.teb``); the names follow
    teb_local_planner's where they match. Weights multiply squared errors."""

    horizon: float = 2.5
    """m of the global path the band covers (its local goal lies this far along)."""
    dt_ref: float = 0.3
    """s: the time interval between poses the band is resized towards."""
    dt_hysteresis: float = 0.1
    """s either side of ``dt_ref`` before a pose is added or removed."""
    min_poses: int = 3
    max_poses: int = 30
    via_spacing: float = 0.5
    """m between the via-points taken from the global path."""
    min_obstacle_dist: float = 0.08
    """m of clearance beyond the body's radius the band keeps from what the laser sees."""
    dynamic_obstacle_dist: float = 0.15
    """m of clearance the band keeps from returns that move, beyond ``min_obstacle_dist``
    (people may turn; their prediction is only at constant velocity)."""
    inflation: float = 0.6
    """m from a return within which the band pays a little to keep away."""
    feasibility_time: float = 1.2
    """s of the optimised band checked against collisions and speed limits."""
    iterations: int = 6
    """Evaluations of residuals and Jacobian (Levenberg-Marquardt steps) per control cycle
    for the band kept from the last cycle; each alternative band tried gets half."""
    weight_viapoint: float = 1.0
    weight_obstacle: float = 50.0
    weight_inflation: float = 0.5
    weight_kinematics: float = 1000.0
    """The non-holonomic constraint: headings agree with the steps between poses."""
    weight_forward: float = 10.0
    """Driving backwards."""
    weight_velocity: float = 10.0
    weight_acceleration: float = 1.0
    weight_time: float = 1.0


@dataclass(frozen=True)
class RobotConfig:
    """One robot's parameters: the control period, what it publishes how often, and its
    body, filter, global planner and local planner (its choice and both tunings).

    Raises ValueError for an unknown ``local_planner``."""

    period: float = 0.1
    """s: the control period (body, laser, controller); the other rates count in it."""
    pose_rate: float = 10.0
    odom_rate: float = 10.0
    scan_rate: float = 5.0
    camera_rate: float = 5.0
    """JPEG frames published per second (0: none)."""
    depth_rate: float = 1.0
    """Registered depth images (with ``camera_info``) published per second (0: none), as
    ROS's ``compressedDepth`` (a 16-bit PNG, tens of kB); fewer than the colour frames."""
    raw_depth: bool = False
    """Publish each depth image also raw (``camera/depth/image``, ``sensor_msgs/Image``:
    800 kB of JSON a frame at 640x480), for a subscriber that cannot read PNG."""
    detect_rate: float = 5.0
    """Camera frames per second the tag detector looks at."""
    status_rate: float = 1.0
    """``nav_status`` and ``localisation`` messages per second when nothing changes (each
    change goes out too)."""
    map_check_rate: float = 0.5
    """Times per second the robot asks again, conditionally, for the bundle of the sub-map
    it is in, so a new version reaches it while it drives there (0: only on entering)."""
    jpeg_quality: int = 80
    camera_timecode: bool = False
    """Stamp each published picture with the wall-clock time code of
    ``cloudnav_core.timecode`` (glass-to-glass delay measurements); it hides the top
    strip of the picture."""
    local_planner: LocalPlanner = "dwa"
    """``dwa`` (``controller``) or ``teb`` (``teb``)."""
    sensors: Sensors = "laser"
    """``laser``, or ``rgbd``: no laser; the scan (published on ``scan`` as
    ``depthimage_to_laserscan`` does, and seen by the local planner) is made from the
    camera's depth, and what it saw is remembered for ``obstacle_memory`` seconds."""
    obstacle_memory: float = 4.0
    """s: how long an RGB-D robot remembers a return that left its field of view."""
    body: BodyLimits = field(default_factory=BodyLimits)
    localisation: FilterParams = field(default_factory=FilterParams)
    planner: PlannerConfig = field(default_factory=PlannerConfig)
    controller: ControllerConfig = field(default_factory=ControllerConfig)
    teb: TebConfig = field(default_factory=TebConfig)

    def __post_init__(self) -> None:
        if self.local_planner not in get_args(LocalPlanner):
            raise ValueError(f"unknown local_planner {self.local_planner!r}")
        if self.sensors not in get_args(Sensors):
            raise ValueError(f"unknown sensors {self.sensors!r}")

    @property
    def planning_radius(self) -> float:
        """m: the radius the global planner inflates obstacles by (body and margin)."""
        return self.body.radius + self.planner.margin
