"""The particle filter on the laser: tag starts, convergence, update rule, resampling,
global localisation and its limits, map swaps, speed; and the Table 3 command."""

from __future__ import annotations

import math
import statistics
import time
from collections.abc import Iterable, Sequence
from typing import Any

import numpy as np
import pytest

from cloudnav_core.params import BeamModel
from cloudnav_core.se2 import Pose
from maps.domain.demo_building import DemoTag, demo_building
from robots.agent.experiments import localisation as experiment
from robots.agent.experiments.localisation import Tick, simulate, submap_grid
from robots.agent.likelihood import Grid, beams_of
from robots.agent.localisation import NotLocalisedError, ParticleFilter, kld_count, odometry_delta
from robots.agent.relocalise import robot_pose_from_tag
from robots.agent.sim.laser import Laser
from robots.agent.sim.world import demo_world, world_from_grid

RES = 0.05
ROOM_ORIGIN = (-0.2, -0.2, 0.0)
ATRIUM_TAG = 1  # Corridor A's east end, beside the door into Atrium 1, facing west


def corridor_filter(**kwargs: Any) -> ParticleFilter:
    """A filter on Corridor A's sub-map, as the robot decodes it from the bundle's PGM."""
    grid, resolution, origin = submap_grid(demo_building(), "CorridorA")
    kwargs.setdefault("seed", 1)
    return ParticleFilter(grid, resolution, origin, **kwargs)


def room(width: float, height: float, blocks: Iterable[Sequence[float]] = ()) -> Grid:
    """A walled room, ``width`` x ``height`` m inside, its inner corner at (0, 0) (the grid's
    origin is ``ROOM_ORIGIN``), with solid ``blocks`` (x0, y0, x1, y1)."""
    wall = round(-ROOM_ORIGIN[0] / RES)
    grid = np.zeros((round(height / RES) + 2 * wall, round(width / RES) + 2 * wall), np.int8)
    grid[:wall], grid[-wall:], grid[:, :wall], grid[:, -wall:] = 100, 100, 100, 100
    for x0, y0, x1, y1 in blocks:
        rows = slice(round(y0 / RES) + wall, round(y1 / RES) + wall)
        grid[rows, round(x0 / RES) + wall : round(x1 / RES) + wall] = 100
    return grid


def tag_start(tag_id: int, distance: float) -> tuple[Pose, np.ndarray]:
    """A robot ``distance`` m in front of a demo tag, facing it, and the pose estimate
    (with its covariance) that an exact reading of the tag gives."""
    tag = next(t for t in demo_building().tags if t.marker_id == tag_id)
    x, y = tag.x + distance * math.cos(tag.yaw), tag.y + distance * math.sin(tag.yaw)
    robot = (x, y, tag.yaw + math.pi)
    estimate = robot_pose_from_tag(tag, seen_from(tag, robot), view_angle=0.0)
    return robot, estimate.covariance


def seen_from(tag: DemoTag, robot: Pose) -> Pose:
    x, y, yaw = robot
    c, s = math.cos(yaw), math.sin(yaw)
    dx, dy = tag.x - x, tag.y - y
    return c * dx + s * dy, -s * dx + c * dy, tag.yaw - yaw


def follow(particle_filter: ParticleFilter, ticks: Iterable[Tick]) -> list[float]:
    """Feed a run to the filter; the position error after each update."""
    errors = []
    for tick in ticks:
        particle_filter.predict(tick.odom_delta)
        if tick.scan is not None and particle_filter.update(tick.scan):
            errors.append(math.dist(particle_filter.pose()[:2], tick.truth[:2]))
    return errors


def last_truth(ticks: Sequence[Tick]) -> Pose:
    return ticks[-1].truth


def scan_at(pose: Pose) -> dict[str, object]:
    laser = Laser(demo_world(), seed=3)
    return laser.message(laser.scan(pose), 0.0)


# --- tracking --------------------------------------------------------------------------


@pytest.mark.slow
def test_a_start_from_a_tag_stays_within_about_15_cm_driving_the_corridor() -> None:
    start, covariance = tag_start(ATRIUM_TAG, 1.2)
    particle_filter = corridor_filter()
    particle_filter.reset(start, covariance)
    ticks = simulate(demo_world(), start, seed=2, duration=35.0, route=[(5.0, 23.2)])
    errors = follow(particle_filter, ticks)
    assert len(errors) > 50  # about 12 m at one update per 0.2 m
    # Over a dozen seeds: 90th percentile 0.07 to 0.12 m, worst 0.10 to 0.16 m.
    assert np.percentile(errors, 90) < 0.15
    assert max(errors) < 0.2


@pytest.mark.slow
def test_a_start_half_a_metre_off_converges() -> None:
    truth = (6.0, 23.0, 0.0)
    particle_filter = corridor_filter()
    particle_filter.reset((6.35, 23.35, 0.15), np.diag([0.5**2, 0.5**2, 0.2**2]))
    ticks = list(simulate(demo_world(), truth, seed=4, duration=15.0, route=[(12.0, 23.2)]))
    errors = follow(particle_filter, ticks)
    assert errors[-1] < 0.1
    assert max(errors[-5:]) < 0.1


# --- when it updates -------------------------------------------------------------------


def test_it_does_not_update_before_20_cm_of_motion() -> None:
    particle_filter = corridor_filter()
    particle_filter.reset((6.0, 23.2, 0.0), np.diag([0.01, 0.01, 0.001]))
    scan = scan_at((6.0, 23.2, 0.0))
    assert not particle_filter.update(scan)
    for _ in range(3):
        particle_filter.predict((0.06, 0.0, 0.0))
        assert not particle_filter.update(scan)  # 6, 12, 18 cm
    particle_filter.predict((0.03, 0.0, 0.0))
    assert particle_filter.update(scan)  # 21 cm
    assert not particle_filter.update(scan)  # counted again from this update


def test_it_updates_after_turning_half_a_radian_on_the_spot() -> None:
    particle_filter = corridor_filter()
    particle_filter.reset((6.0, 23.2, 0.0), np.diag([0.01, 0.01, 0.001]))
    particle_filter.predict((0.0, 0.0, 0.45))
    assert not particle_filter.update(scan_at((6.0, 23.2, 0.45)))
    particle_filter.predict((0.0, 0.0, 0.06))
    assert particle_filter.update(scan_at((6.0, 23.2, 0.51)))


def test_between_updates_the_particles_follow_odometry() -> None:
    particle_filter = corridor_filter()
    particle_filter.reset((6.0, 23.2, math.pi / 2), np.diag([1e-6, 1e-6, 1e-8]))
    particle_filter.predict(odometry_delta((0.0, 0.0, 0.0), (0.1, 0.0, 0.2)))
    x, y, yaw = particle_filter.pose()
    assert (x, y, yaw) == pytest.approx((6.0, 23.3, math.pi / 2 + 0.2), abs=1e-3)


# --- resampling ------------------------------------------------------------------------


@pytest.mark.slow
def test_resampling_keeps_the_particle_count_within_its_bounds() -> None:
    particle_filter = corridor_filter(particles=200, min_particles=50, max_particles=3000)
    particle_filter.reset_uniform()
    counts = [len(particle_filter.particles())]
    for tick in simulate(
        demo_world(), (5.0, 23.2, 0.0), seed=5, duration=15.0, route=[(12.0, 23.2)]
    ):
        particle_filter.predict(tick.odom_delta)
        if tick.scan is not None and particle_filter.update(tick.scan):
            counts.append(len(particle_filter.particles()))
    assert counts[0] == 3000  # a uniform start uses them all
    assert all(50 <= count <= 3000 for count in counts)
    assert counts[-1] < 500  # fewer once the cloud has gathered


def test_kld_sampling_keeps_few_for_a_tight_cloud_and_many_for_a_spread_one() -> None:
    rng = np.random.default_rng(0)
    tight = rng.normal([3.2, 1.2, 0.1], 0.01, (5000, 3))
    spread = np.column_stack([rng.uniform(0, 20, (5000, 2)), rng.uniform(-3, 3, 5000)])
    assert kld_count(tight, 100, 5000, 0.01, 0.99) == 100
    assert kld_count(spread, 100, 5000, 0.01, 0.99) == 5000


# --- global localisation ---------------------------------------------------------------


@pytest.mark.slow
def test_a_uniform_start_converges_in_a_small_distinctive_room() -> None:
    # A cut corner, a notch and a post: no pose looks like another once the robot moves.
    grid = room(4.0, 3.0, [(2.6, 2.0, 4.0, 3.0), (1.6, 0.0, 1.9, 0.4), (0.0, 2.2, 0.5, 2.5)])
    world = world_from_grid(grid, ROOM_ORIGIN, RES)
    for seed in range(3):
        particle_filter = ParticleFilter(grid, RES, ROOM_ORIGIN, seed=seed)  # 5000, as AMCL
        particle_filter.reset_uniform()
        ticks = simulate(
            world,
            (0.8, 1.0, 0.0),
            seed=seed,
            duration=15.0,
            route=[(3.0, 1.0), (1.2, 2.2), (0.8, 1.0)],
        )
        assert max(follow(particle_filter, ticks)[-10:]) < 0.1


@pytest.mark.slow
def test_in_a_symmetric_corridor_a_uniform_start_ends_at_the_truth_or_its_mirror_image() -> None:
    """The paper's point about global initialisation: in a corridor that looks the same
    from both ends, driving does not tell the two apart, and the filter settles on either
    with confidence. A tag tells them apart at once."""
    grid = room(10.0, 2.0)
    world = world_from_grid(grid, ROOM_ORIGIN, RES)
    outcomes = []
    for seed in range(4):
        particle_filter = ParticleFilter(grid, RES, ROOM_ORIGIN, seed=seed, max_particles=2000)
        particle_filter.reset_uniform()
        ticks = list(
            simulate(
                world, (3.0, 1.0, 0.0), seed=seed, duration=20.0, route=[(6.0, 1.0), (3.0, 1.0)]
            )
        )
        follow(particle_filter, ticks)
        x, y, _ = last_truth(ticks)
        mirror = (10.0 - x, 2.0 - y)  # turned half a circle about the corridor's centre
        estimate = particle_filter.pose()[:2]
        assert math.dist(estimate, (x, y)) < 0.2 or math.dist(estimate, mirror) < 0.2
        outcomes.append(math.dist(estimate, (x, y)) < 0.2)
        assert np.sqrt(np.diag(particle_filter.covariance())[:2]).max() < 0.2  # confident
    assert any(outcomes)
    assert not all(outcomes)


# --- maps ------------------------------------------------------------------------------


@pytest.mark.slow
def test_swapping_to_the_next_sub_map_keeps_the_pose_and_goes_on_tracking() -> None:
    start, covariance = tag_start(ATRIUM_TAG, 1.2)
    particle_filter = corridor_filter()
    particle_filter.reset(start, covariance)
    atrium = submap_grid(demo_building(), "Atrium1")
    ticks = simulate(
        demo_world(), start, seed=6, duration=20.0, route=[(17.2, 23.8), (19.0, 23.8), (21.0, 22.4)]
    )
    swapped, errors = False, []
    for tick in ticks:
        if not swapped and tick.truth[0] > 18.4:  # through the door
            before = particle_filter.pose()
            particle_filter.set_map(*atrium)
            assert particle_filter.pose() == before
            swapped = True
        errors += follow(particle_filter, [tick])
    assert swapped
    assert max(errors) < 0.2  # over ten seeds, at most 0.13 m


def test_a_map_in_another_frame_needs_a_reset() -> None:
    particle_filter = corridor_filter()
    particle_filter.reset((6.0, 23.2, 0.0), np.diag([0.01, 0.01, 0.001]))
    grid, resolution, origin = submap_grid(demo_building(), "Atrium1")
    particle_filter.set_map(grid, resolution, origin, shared_frame=False)
    with pytest.raises(NotLocalisedError):
        particle_filter.pose()
    particle_filter.predict((0.3, 0.0, 0.0))
    assert not particle_filter.update(scan_at((22.0, 23.2, 0.0)))
    particle_filter.reset((22.0, 23.2, 0.0), np.diag([0.01, 0.01, 0.001]))
    assert particle_filter.pose()[:2] == pytest.approx((22.0, 23.2), abs=0.03)


# --- estimates -------------------------------------------------------------------------


def test_a_reset_draws_its_particles_from_the_given_gaussian() -> None:
    covariance = np.array([[0.04, 0.01, 0.0], [0.01, 0.09, 0.0], [0.0, 0.0, 0.01]])
    particle_filter = corridor_filter(particles=5000)
    particle_filter.reset((6.0, 23.2, 0.5), covariance)
    assert len(particle_filter.particles()) == 5000
    assert particle_filter.pose() == pytest.approx((6.0, 23.2, 0.5), abs=0.01)
    np.testing.assert_allclose(particle_filter.covariance(), covariance, atol=0.005)


def test_the_mean_heading_is_circular_across_half_a_turn() -> None:
    particle_filter = corridor_filter()
    particle_filter.reset((6.0, 23.2, math.pi), np.diag([0.01, 0.01, 0.05**2]))
    yaw = particle_filter.pose()[2]
    assert abs(abs(yaw) - math.pi) < 0.02  # not the arithmetic mean, near 0
    assert particle_filter.covariance()[2, 2] == pytest.approx(0.05**2, rel=0.2)


@pytest.mark.slow
def test_amcls_sum_of_cubes_model_tracks_but_more_loosely() -> None:
    start, covariance = tag_start(ATRIUM_TAG, 1.2)
    spreads = {}
    for model in ("likelihood_field_prob", "likelihood_field"):
        particle_filter = corridor_filter(laser_model=model)
        particle_filter.reset(start, covariance)
        ticks = simulate(demo_world(), start, seed=2, duration=25.0, route=[(8.0, 23.2)])
        assert max(follow(particle_filter, ticks)) < 0.5
        spreads[model] = math.sqrt(particle_filter.covariance()[0, 0])
    assert spreads["likelihood_field"] > 2 * spreads["likelihood_field_prob"]


# --- inputs ----------------------------------------------------------------------------


def test_a_rosbridge_scan_with_nulls_reads_like_one_with_infinities() -> None:
    laser = Laser(demo_world(), seed=0)
    ranges = laser.scan((5.0, 23.2, 0.0))  # inf ahead: 12.8 m of corridor, 8 m range
    as_json = laser.message(ranges, 0.0)
    as_array = {**as_json, "ranges": ranges}
    assert None in as_json["ranges"]
    from_json, from_array = beams_of(as_json, BeamModel()), beams_of(as_array, BeamModel())
    np.testing.assert_allclose(from_json.x, from_array.x)
    assert 0 < from_json.count < 60  # no-return beams are left out of the 60


def test_it_refuses_unknown_parameters() -> None:
    with pytest.raises(TypeError):
        corridor_filter(alpha9=0.1)
    with pytest.raises(ValueError, match="laser_model"):
        corridor_filter(laser_model="beam")
    with pytest.raises(ValueError, match="particle counts"):
        corridor_filter(particles=50, min_particles=100)


# --- speed -----------------------------------------------------------------------------


def test_one_update_of_500_particles_and_60_beams_takes_a_few_milliseconds() -> None:
    particle_filter = corridor_filter(particles=500, min_particles=500, max_particles=500)
    particle_filter.reset((6.0, 23.2, 0.0), np.diag([0.1, 0.1, 0.05]))
    scan = scan_at((6.0, 23.2, 0.0))
    seconds = []
    for _ in range(30):
        particle_filter.predict((0.2, 0.0, 0.0))
        started = time.process_time()
        assert particle_filter.update(scan)
        seconds.append(time.process_time() - started)
    assert len(particle_filter.particles()) == 500
    assert statistics.median(seconds) < 0.01  # about 1 ms on the development machine


# --- the experiment --------------------------------------------------------------------


@pytest.mark.slow
def test_the_experiment_prints_table_3_beside_the_papers_headings(
    capsys: pytest.CaptureFixture[str],
) -> None:
    assert experiment.main(["--trials", "1", "--sensor", "laser"]) == 0
    out = capsys.readouterr().out
    assert "Table 3 (360-degree laser" in out
    for name in ("tag", "random", "global"):
        assert f"| {name} " in out
    assert "paper 30 s" in out
    assert "n/a" in out
