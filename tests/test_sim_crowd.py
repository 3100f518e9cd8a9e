"""The simulator's moving obstacles: people walking seeded routes, and robots seeing
people and one another in their lasers and cameras."""

from __future__ import annotations

import math

import numpy as np
import pytest

from robots.agent.fleet import demo_crowd
from robots.agent.sim.crowd import (
    GIVE_WAY,
    PASSING,
    START_CLEARANCE,
    TURN_BACK,
    WALKING_SPEEDS,
    Crowd,
    Person,
    seeded_people,
)
from robots.agent.sim.hardware import SimHardware
from robots.agent.sim.laser import LaserSpec
from robots.agent.sim.world import demo_world

# In Corridor A (walls at y = 22.0 and 24.4), facing east along it.
POSE = (6.0, 23.2, 0.0)


def beam(spec: LaserSpec, angle: float) -> int:
    return round((angle - spec.angle_min) / spec.angle_increment) % spec.beams


def standing(x: float, y: float) -> Person:
    return Person([(x, y)], speed=1.0)


def test_seeded_people_walk_at_a_walking_pace_and_keep_off_the_walls() -> None:
    world = demo_world()
    crowd = demo_crowd(world, 8, seed=3)
    previous = [p.position() for p in crowd.people]
    fastest, moved = 0.0, set()
    for second in range(1, 61):
        crowd.advance_to(float(second))
        for index, person in enumerate(crowd.people):
            step = math.dist(previous[index], person.position())
            fastest = max(fastest, step)
            moved |= {index} if step > 0 else set()
            assert world.clearance(person.x, person.y, 1.0) >= person.radius
        previous = [p.position() for p in crowd.people]
    assert moved == set(range(8))
    assert fastest <= WALKING_SPEEDS[1] + 1e-9
    speeds = [p.speed for p in crowd.people]
    assert all(WALKING_SPEEDS[0] <= s <= WALKING_SPEEDS[1] for s in speeds)


def test_the_same_seed_gives_the_same_walks_and_another_seed_others() -> None:
    world = demo_world()
    runs = [demo_crowd(world, 4, seed) for seed in (5, 5, 6)]
    for crowd in runs:
        crowd.advance_to(20.0)
    where = [[p.position() for p in crowd.people] for crowd in runs]
    assert where[0] == where[1]
    assert where[0] != where[2]


def test_a_robot_laser_sees_a_person_and_another_robot() -> None:
    world = demo_world()
    crowd = Crowd(world, [standing(7.5, 23.2)])
    spec = LaserSpec(noise_sigma=0.0)
    me = SimHardware(world, POSE, crowd=crowd)
    SimHardware(world, (6.0, 22.6, 0.0), crowd=crowd)  # beside me, to the right
    me.laser.spec = spec
    ranges = me.scan()
    assert ranges[beam(spec, 0.0)] == pytest.approx(1.5 - 0.25, abs=0.03)
    assert ranges[beam(spec, -math.pi / 2)] == pytest.approx(0.6 - 0.18, abs=0.03)


def test_a_person_shows_in_the_camera_in_front_of_the_wall_and_hides_a_tag() -> None:
    world = demo_world()
    entrance = (3.1, 22.6, 0.0)  # facing the entrance tag from the porch, 0.5 m away
    bare = SimHardware(world, entrance)
    crowd = Crowd(world, [standing(3.3, 22.6)])
    hidden = SimHardware(world, entrance, crowd=crowd)
    seen, blocked = bare.image(), hidden.image()
    middle = seen.shape[1] // 2
    assert abs(int(blocked[60, middle]) - int(seen[60, middle])) > 20  # a person above the tag
    detector = bare.camera.model
    from robots.agent.perception import TagDetector

    assert TagDetector(detector).detect(seen)
    assert not TagDetector(detector).detect(blocked)


def test_a_robot_bumps_into_a_person_instead_of_driving_through() -> None:
    world = demo_world()
    crowd = Crowd(world, [standing(6.6, 23.2)])
    robot = SimHardware(world, POSE, crowd=crowd)
    for _ in range(30):
        robot.command(0.5, 0.0)
        robot.advance(0.1)
    assert robot.true_pose[0] < 6.6 - 0.25 - 0.18 + 0.02


def test_a_person_gives_way_to_a_robot_then_turns_back() -> None:
    world = demo_world()
    walker = Person([(10.0, 23.2), (5.0, 23.2)], speed=1.0)
    crowd = Crowd(world, [walker])
    SimHardware(world, POSE, crowd=crowd)  # at x = 6.0, in the person's way
    crowd.advance_to(6.0)
    stop = walker.x
    assert stop - 6.0 == pytest.approx(0.25 + 0.18 + GIVE_WAY, abs=0.06)
    crowd.advance_to(6.0 + TURN_BACK + 2.0)
    assert walker.x > stop + 1.0  # walking away, back the way they came


def test_a_person_walking_past_a_standing_robot_keeps_clear_of_it() -> None:
    world = demo_world()
    # Their path passes the robot's edge with 3 mm to spare (a contact to the bench):
    # nearer than PASSING, so they stop short of it instead of brushing past.
    aside = 0.25 + 0.18 + 0.003
    assert aside < 0.25 + 0.18 + PASSING
    walker = Person([(10.0, 23.2 + aside), (5.0, 23.2 + aside)], speed=1.4)
    crowd = Crowd(world, [walker])
    hardware = SimHardware(world, POSE, crowd=crowd)
    for step in range(1, 121):
        crowd.advance_to(step * 0.05)
        gap = math.dist(walker.position(), POSE[:2]) - walker.radius - hardware.body.radius
        assert gap > GIVE_WAY / 2
    assert walker.x > POSE[0]  # they stopped before passing it


def test_seeded_people_start_clear_of_the_robots_starts() -> None:
    world = demo_world()
    robot = (5.0, 23.2)  # the west end of Corridor A, where the bench's robot starts
    for seed in range(40):
        for person in seeded_people(world, 8, seed, keep_clear=[robot]):
            assert math.dist(person.route[0], robot) >= START_CLEARANCE


def test_a_robot_seeking_person_walks_towards_a_robot_in_sight() -> None:
    world = demo_world()
    seeker = Person([(12.0, 22.6), (12.0, 23.8)], speed=1.0, seeks_robots=True)
    crowd = Crowd(world, [seeker])
    SimHardware(world, (9.0, 23.2, 0.0), crowd=crowd)
    before = math.dist(seeker.position(), (9.0, 23.2))
    crowd.advance_to(2.0)
    assert math.dist(seeker.position(), (9.0, 23.2)) < before - 1.5
    assert np.hypot(*seeker.velocity) == pytest.approx(0.0) or seeker.x < 12.0
