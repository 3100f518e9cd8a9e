"""Where the simulated camera looks: a tag of the world by marker id, and the robot pose
that faces it from a distance and angle."""

from __future__ import annotations

import math

from cloudnav_core.camera import CameraModel
from robots.agent.sim.world import SimTag, World

ENTRANCE = 0  # marker id of the tag beside the building's entrance, facing west


def tag_of(world: World, marker_id: int) -> SimTag:
    return next(tag for tag in world.tags if tag.marker_id == marker_id)


def facing(tag: SimTag, distance: float, angle: float = 0.0) -> tuple[float, float, float]:
    """Robot pose whose camera is ``distance`` m (on the floor plan) from the marker centre,
    ``angle`` degrees off the tag's normal, looking at it."""
    direction = tag.yaw + math.radians(angle)
    yaw = direction + math.pi
    mount = CameraModel().mount_x
    x = tag.x + distance * math.cos(direction) - mount * math.cos(yaw)
    y = tag.y + distance * math.sin(direction) - mount * math.sin(yaw)
    return x, y, yaw
