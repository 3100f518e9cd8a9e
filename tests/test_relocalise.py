"""Relocalisation: the robot's pose from a tag's stored pose and how the robot sees it."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pytest

from robots.agent.perception import TagDetector
from robots.agent.relocalise import PoseEstimate, TagNoiseModel, relocalise, robot_pose_from_tag
from robots.agent.sim.camera import Camera
from robots.agent.sim.world import demo_world
from tests.support.sim_camera import facing, tag_of


@dataclass(frozen=True)
class StoredTag:
    x: float
    y: float
    yaw: float


ATRIUM_TAG = 3  # on Atrium 1's south wall, facing north into the open atrium


def seen_from(tag: StoredTag, robot: tuple[float, float, float]) -> tuple[float, float, float]:
    """Exactly how a robot at ``robot`` sees ``tag``: its pose in the robot frame."""
    x, y, yaw = robot
    dx, dy = tag.x - x, tag.y - y
    c, s = math.cos(yaw), math.sin(yaw)
    return c * dx + s * dy, -s * dx + c * dy, tag.yaw - yaw


def angle_error(a: float, b: float) -> float:
    return math.degrees(abs((a - b + math.pi) % (2 * math.pi) - math.pi))


def test_an_exact_measurement_gives_back_the_exact_pose() -> None:
    tag = StoredTag(4.0, -2.0, 2.5)
    robot = (3.1, -1.2, -0.7)
    estimate = robot_pose_from_tag(tag, seen_from(tag, robot), view_angle=0.3)
    assert (estimate.x, estimate.y) == pytest.approx(robot[:2])
    assert angle_error(estimate.yaw, robot[2]) < 1e-9


@pytest.mark.parametrize("distance", [0.4, 0.8, 1.2, 1.5])
@pytest.mark.parametrize("angle", [0.0, 20.0, 45.0, -30.0])
def test_it_round_trips_a_rendered_view_within_a_few_cm_and_degrees(
    distance: float, angle: float
) -> None:
    world = demo_world()
    tag = tag_of(world, ATRIUM_TAG)
    x, y, yaw = facing(tag, distance, angle)
    robot = (x, y, yaw + 0.1)  # not quite looking at the tag
    (detection,) = TagDetector(read_qr=False).detect(Camera(world).render(robot))
    estimate = relocalise(tag, detection)
    assert math.dist((estimate.x, estimate.y), robot[:2]) < 0.04
    assert angle_error(estimate.yaw, robot[2]) < 1.5
    turn = (estimate.yaw - robot[2] + math.pi) % (2 * math.pi) - math.pi
    error = np.array([estimate.x - robot[0], estimate.y - robot[1], turn])
    assert error @ np.linalg.solve(estimate.covariance, error) < 9  # within 3 sigma


def test_its_covariance_grows_with_distance_and_viewing_angle() -> None:
    tag = StoredTag(0.0, 0.0, 0.0)

    def spread(distance: float, angle: float) -> tuple[float, float]:
        direction = math.radians(angle)
        robot = (
            distance * math.cos(direction),
            distance * math.sin(direction),
            direction + math.pi,
        )
        estimate = robot_pose_from_tag(tag, seen_from(tag, robot), math.radians(angle))
        position = math.sqrt(estimate.covariance[0, 0] + estimate.covariance[1, 1])
        return position, math.sqrt(estimate.covariance[2, 2])

    near, far = spread(0.5, 0.0), spread(1.5, 0.0)
    assert far[0] > 2 * near[0]
    assert far[1] > near[1]
    assert spread(1.0, 50.0)[0] > spread(1.0, 10.0)[0]


def test_its_covariance_is_symmetric_positive_definite_and_ros_shaped() -> None:
    tag = StoredTag(1.0, 2.0, math.pi / 2)
    estimate = robot_pose_from_tag(tag, (0.9, 0.2, -2.9), view_angle=0.4)
    covariance = estimate.covariance
    np.testing.assert_allclose(covariance, covariance.T)
    assert np.linalg.eigvalsh(covariance).min() > 0
    ros = estimate.ros_covariance()
    assert len(ros) == 36
    assert (ros[0], ros[7], ros[35]) == pytest.approx(np.diag(covariance).tolist())
    assert (ros[1], ros[5], ros[30]) == pytest.approx(
        [covariance[0, 1], covariance[0, 2], covariance[2, 0]]
    )
    assert ros[14] == ros[21] == ros[28] == 0.0  # z, roll and pitch are not estimated


def test_an_ambiguous_detection_widens_the_yaw_spread() -> None:
    tag = StoredTag(0.0, 0.0, 0.0)
    seen = (1.5, 0.0, math.pi)
    plain = robot_pose_from_tag(tag, seen, 0.0)
    doubtful = robot_pose_from_tag(tag, seen, 0.0, ambiguity=math.radians(30))
    assert math.sqrt(doubtful.covariance[2, 2]) > math.radians(30)
    assert doubtful.covariance[1, 1] > 10 * plain.covariance[1, 1]


def test_its_noise_model_can_be_replaced() -> None:
    tag = StoredTag(0.0, 0.0, 0.0)
    seen = (1.0, 0.0, math.pi)
    default = robot_pose_from_tag(tag, seen, 0.0)
    careful = robot_pose_from_tag(tag, seen, 0.0, TagNoiseModel(tag_position=0.1))
    assert isinstance(careful, PoseEstimate)
    assert careful.covariance[0, 0] > default.covariance[0, 0]
