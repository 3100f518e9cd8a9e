"""The simulator as a robot's hardware (``robots.agent.hardware.Hardware``): a
differential-drive body, a ray-cast laser, a rendered camera with depth and a battery in
one ``World``, optionally among a crowd of people and other robots.

A robot with ``sensors="rgbd"`` has no laser: its scan is made from the camera's depth
(``robots.agent.depth_scan``), as ``depthimage_to_laserscan`` makes one on a robot with
an RGB-D camera only, and spans the camera's field of view."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from cloudnav_core.camera import CameraModel
from cloudnav_core.messages import Json, Odometry, laser_scan
from cloudnav_core.params import BodyLimits, Sensors
from cloudnav_core.se2 import Pose
from robots.agent.depth_scan import DepthScanSpec, depth_to_scan
from robots.agent.sim.battery import SimBattery
from robots.agent.sim.body import DiffDriveBody
from robots.agent.sim.camera import Camera
from robots.agent.sim.crowd import Crowd
from robots.agent.sim.laser import Laser, LaserSpec
from robots.agent.sim.world import World

DEPTH_SCAN_FRAME = "camera_depth_frame"


class SimHardware:
    """The body, laser and camera of one robot in ``world``, starting at ``pose``; the
    body moves within ``limits`` (the default robot's without).

    With a ``crowd``, the body joins it: this robot's laser, camera and bumpers see its
    people and the other robots in it, and they see this one. Advancing the hardware
    walks the crowd on to the body's time (the first robot there moves it)."""

    def __init__(
        self,
        world: World,
        pose: Pose,
        seed: int = 0,
        limits: BodyLimits | None = None,
        crowd: Crowd | None = None,
        sensors: Sensors = "laser",
    ) -> None:
        self.crowd = crowd
        self.sensors = sensors
        self.body = DiffDriveBody(world, pose, limits=limits, seed=seed)
        movers = None
        if crowd is not None:
            crowd.join(self.body)
            movers = self.body.others = crowd.movers_for(self.body)
        self.laser = Laser(world, LaserSpec(), seed=seed + 1, movers=movers)
        self.camera = Camera(world, CameraModel(), seed=seed + 2, movers=movers)
        self.camera_model = model = self.camera.model
        self.battery = SimBattery()
        self.depth_scan = DepthScanSpec()
        if sensors == "rgbd":
            self.scan_angles = self.depth_scan.angles(model)
            self.scan_mount: Pose = (model.mount_x, 0.0, 0.0)
        else:
            self.scan_angles = self.laser.spec.angles()
            self.scan_mount = (self.laser.spec.mount_x, 0.0, 0.0)

    @property
    def true_pose(self) -> Pose:
        """Ground truth: for the simulator and tests only."""
        return self.body.pose

    @property
    def odom_pose(self) -> Pose:
        return self.body.odom_pose

    @property
    def reported_velocity(self) -> tuple[float, float]:
        """The velocity the wheel encoders report (with their scale errors)."""
        linear, angular = self.body.velocity
        return linear * self.body.noise.linear_scale, angular * self.body.noise.angular_scale

    def advance(self, seconds: float) -> None:
        self.body.advance(seconds)
        self.battery.drain(seconds, *self.body.velocity)
        if self.crowd is not None:
            self.crowd.advance_to(self.body.time)

    def command(self, linear: float, angular: float) -> None:
        """Ask for a velocity; the body clamps it to its limits."""
        self.body.command(linear, angular)

    def scan(self) -> NDArray[np.float32]:
        if self.sensors == "rgbd":
            rows = self.camera.depth_rows(self.body.pose, self.depth_scan.rows(self.camera.model))
            return depth_to_scan(rows, self.camera.model, self.depth_scan)
        return self.laser.scan(self.body.pose)

    def scan_message(self, ranges: NDArray[np.float32], seconds: float) -> Json:
        if self.sensors == "laser":
            return self.laser.message(ranges, seconds)
        spec, angles = self.depth_scan, self.scan_angles
        return dict(
            laser_scan(
                DEPTH_SCAN_FRAME,
                ranges.tolist(),
                seconds,
                angle_min=float(angles[0]),
                angle_max=float(angles[-1]),
                angle_increment=float(angles[1] - angles[0]),
                time_increment=0.0,  # a camera takes every column at once
                scan_time=1 / 30,
                range_min=spec.range_min,
                range_max=spec.range_max,
            )
        )

    def odometry_message(self, seconds: float) -> Odometry:
        return self.body.odometry_message(seconds=seconds)

    def image(self) -> NDArray[np.uint8]:
        return self.camera.render(self.body.pose)

    def image_and_depth(self) -> tuple[NDArray[np.uint8], NDArray[np.float32]]:
        """A frame and its registered depth (metres along the optical axis)."""
        image, depth = self.camera.capture(self.body.pose)
        assert depth is not None
        return image, depth
