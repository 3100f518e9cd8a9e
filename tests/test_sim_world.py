"""The simulated world: grid ray casting, obstacles, collision discs, demo tags."""

from __future__ import annotations

import math

import numpy as np
import pytest

from maps.domain.demo_building import demo_building
from maps.domain.tagpayload import parse_payload
from robots.agent.sim.world import (
    OBSTACLE,
    WALL,
    Box,
    Cylinder,
    World,
    demo_world,
    world_from_grid,
)


def brute_force_range(world: World, x: float, y: float, angle: float, reach: float) -> float:
    """March in 0.5 mm steps to the first solid cell."""
    for step in np.arange(0.0, reach, 0.0005):
        row, col = world.cell_of(x + step * math.cos(angle), y + step * math.sin(angle))
        inside = 0 <= row < world.cells.shape[0] and 0 <= col < world.cells.shape[1]
        if inside and world.cells[row, col]:
            return float(step)
    return math.inf


@pytest.mark.slow
def test_its_rays_end_where_a_fine_march_meets_a_wall() -> None:
    world = demo_world().with_obstacles(Cylinder(8.0, 23.0, 0.3))
    rng = np.random.default_rng(1)
    for _ in range(6):
        x, y = rng.uniform(4.0, 17.0), rng.uniform(22.2, 24.2)
        angles = rng.uniform(-math.pi, math.pi, 8)
        hits = world.cast(x, y, angles, 8.0)
        for angle, distance in zip(angles, hits.distance, strict=True):
            expected = brute_force_range(world, x, y, angle, 8.0)
            assert distance == pytest.approx(expected, abs=0.001)


def test_it_tells_walls_from_obstacles_and_which_face_was_hit() -> None:
    world = demo_world().with_obstacles(Box(6.0, 23.0, 6.4, 23.4))
    hits = world.cast(5.0, 23.2, np.array([0.0, math.pi / 2]), 8.0)
    assert hits.material.tolist() == [OBSTACLE, WALL]
    assert hits.x_face.tolist() == [True, False]


def test_a_ray_from_inside_a_wall_ends_at_once() -> None:
    world = demo_world()
    assert world.cast(3.7, 23.0, np.array([0.0]), 8.0).distance[0] == 0.0


def test_it_knows_when_a_disc_touches_a_wall() -> None:
    world = demo_world()
    assert world.disc_is_free(5.0, 23.2, 0.18)
    assert world.disc_is_free(5.0, 24.4 - 0.181, 0.18)
    assert not world.disc_is_free(5.0, 24.4 - 0.179, 0.18)


def test_unknown_cells_are_free_and_obstacles_keep_walls() -> None:
    grid = np.array([[-1, 0, 100]], np.int8)
    world = world_from_grid(grid, (0.0, 0.0), 1.0, obstacles=[Box(0.0, 0.0, 3.0, 1.0)])
    assert world.cells.tolist() == [[OBSTACLE, OBSTACLE, WALL]]


def test_its_demo_tags_carry_the_payload_of_the_submap_they_lead_into() -> None:
    world = demo_world("https://cloud.example")
    building = demo_building("https://cloud.example")
    assert len(world.tags) == len(building.tags)
    for sim_tag, tag in zip(world.tags, building.tags, strict=True):
        payload = parse_payload(sim_tag.payload)
        assert payload.cloud_location == "https://cloud.example"
        assert payload.map_id == f"{building.code}/{tag.links_to}"
        assert (sim_tag.x, sim_tag.y, sim_tag.yaw) == (tag.x, tag.y, tag.yaw)
