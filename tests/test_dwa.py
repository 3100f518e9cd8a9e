"""The dynamic window (DWA) among people: what moves is predicted, and the robot lets a
person cross in front of it rather than meet them where they will be."""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from cloudnav_core.params import RobotConfig
from cloudnav_core.se2 import Pose, wrap
from robots.agent.navigation.clearance import LocalObstacles
from robots.agent.navigation.commands import Command
from robots.agent.navigation.driver import Driver
from robots.agent.sim.crowd import PERSON_RADIUS, Discs, cast_discs

ANGLES = np.radians(np.arange(360.0))


def scan_of(person: tuple[float, float], pose: Pose) -> LocalObstacles:
    """What a 360-beam laser on the robot at ``pose`` sees of one person."""
    disc = Discs(
        np.array([person[0]]),
        np.array([person[1]]),
        np.array([PERSON_RADIUS]),
        np.array([1.7]),
        np.array([True]),
    )
    ranges, _ = cast_discs(pose[0], pose[1], ANGLES + pose[2], disc)
    return LocalObstacles.from_scan(np.where(ranges <= 3.5, ranges, np.inf), ANGLES)


def drive_past_a_crossing_person(speed: float, start_y: float) -> float:
    """Drive a DWA robot along the x axis while a person who gives no way crosses it
    at ``speed`` from ``start_y``; the smallest gap between them (metres)."""
    config = RobotConfig(local_planner="dwa")
    driver = Driver(config)
    pose: Pose = (0.0, 0.0, 0.0)
    velocity = (0.4, 0.0)
    target: Pose = (6.0, 0.0, 0.0)
    smallest = math.inf
    for cycle in range(60):
        seconds = cycle * config.period
        person = (0.9, start_y + speed * seconds)
        gap = math.dist(pose[:2], person) - PERSON_RADIUS - config.body.radius
        smallest = min(smallest, gap)
        obstacles = scan_of(person, pose)
        command = driver.drive(target, None, pose, velocity, obstacles, seconds, pose).command
        assert command is not None
        velocity = command
        x, y, yaw = pose
        yaw = wrap(yaw + command[1] * config.period)
        pose = (
            x + command[0] * config.period * math.cos(yaw),
            y + command[0] * config.period * math.sin(yaw),
            yaw,
        )
    return smallest


def test_a_dwa_robot_lets_a_person_crossing_fast_pass_in_front_of_it() -> None:
    # At 1.4 m/s from 2.1 m aside, the person reaches the robot's way at x = 0.9 just as
    # a robot driving on at 0.4 to 0.5 m/s would: seen standing still, they run into it.
    assert drive_past_a_crossing_person(1.4, -2.1) > 0.02


def test_a_dwa_robot_backs_away_from_a_person_walking_into_it() -> None:
    config = RobotConfig(local_planner="dwa")
    driver = Driver(config)
    pose: Pose = (0.0, 0.0, 0.0)
    commands = []
    for cycle in range(6):
        seconds = cycle * config.period
        person = (0.9 - 0.6 * seconds, 0.0)  # walking straight at the robot, on its way
        obstacles = scan_of(person, pose)
        drive = driver.drive((1.6, 0.0, 0.0), None, pose, (0.0, 0.0), obstacles, seconds, pose)
        assert drive.command is not None
        commands.append(drive.command)
    assert commands[-1][0] < 0


# --- a robot that sees only ahead ------------------------------------------------------


def first_command(may_enter: Callable[[NDArray[np.float64]], NDArray[np.bool_]]) -> Command:
    """The command of a camera-only robot's first cycle toward a goal 3 m straight ahead,
    on open floor, already driving at 0.4 m/s; ``may_enter`` as the depth memory gives it."""
    config = RobotConfig(local_planner="dwa", sensors="rgbd")
    driver = Driver(config)
    obstacles = LocalObstacles(np.zeros((0, 2)), may_enter=may_enter)
    pose: Pose = (0.0, 0.0, 0.0)
    drive = driver.drive((3.0, 0.0, 0.0), None, pose, (0.4, 0.0), obstacles, 0.0, pose)
    assert drive.command is not None
    return drive.command


def test_a_camera_only_robot_drives_on_onto_floor_it_may_enter() -> None:
    linear, _ = first_command(lambda points: np.ones(len(points), bool))
    assert linear > 0.2


def test_a_camera_only_robot_kept_off_the_floor_on_its_left_stops_and_turns_to_look() -> None:
    linear, angular = first_command(lambda points: points[:, 1] < 0.05)
    assert linear == 0.0
    assert angular > 0.3  # towards the floor it may not enter


def test_floor_off_limits_far_to_one_side_does_not_hold_it_back() -> None:
    linear, _ = first_command(lambda points: points[:, 1] > -1.0)
    assert linear > 0.2
