"""A simulated building that differs from its stored maps, in seeded ways: moved and new
furniture, a closed door, a new wall, a room no sub-map covers."""

from __future__ import annotations

import math

import numpy as np

from cloudnav_core.grid import cell_of
from maps.domain.demo_building import demo_building
from robots.agent.sim.changes import (
    ChangeConfig,
    changed_demo_world,
    changed_grid,
    plan_changes,
)


def test_the_same_seed_gives_the_same_changes_and_another_seed_others() -> None:
    assert plan_changes(3) == plan_changes(3)
    assert {plan_changes(seed) for seed in range(4)} != {plan_changes(3)}


def test_every_kind_of_change_is_drawn_as_configured() -> None:
    changes = plan_changes(1, ChangeConfig(moved=2, added=3, closed_doors=1, walls=2, rooms=1))
    assert len(changes.emptied) == 2
    assert len(changes.filled) == 2 + 3
    assert len(changes.walls) == 1 + 2
    assert len(changes.rooms) == 1
    assert len(changes.notes) == 2 + 3 + 1 + 2 + 1
    assert plan_changes(1, ChangeConfig(0, 0, 0, 0, 0)).notes == ()


def test_the_truth_differs_from_the_stored_maps_where_the_changes_are() -> None:
    building = demo_building()
    changes = plan_changes(2)
    truth = changed_grid(changes, building)
    room = changes.rooms[0]
    inside = cell_of(
        ((room.interior[0] + room.interior[2]) / 2, room.interior[1] + 0.5),
        building.world_origin,
        building.resolution,
    )
    assert building.world[inside] == -1  # no map covers it...
    assert truth[inside] == 0  # ...yet it is a room
    door = cell_of(
        ((room.door[0] + room.door[2]) / 2, (room.door[1] + room.door[3]) / 2),
        building.world_origin,
        building.resolution,
    )
    assert building.world[door] == 100  # the wall the room's door was cut through
    assert truth[door] == 0
    for wall in changes.walls:
        centre = cell_of(
            ((wall[0] + wall[2]) / 2, (wall[1] + wall[3]) / 2),
            building.world_origin,
            building.resolution,
        )
        assert building.world[centre] == 0
        assert truth[centre] == 100
    assert np.array_equal(building.world, demo_building().world)  # the maps are untouched


def test_the_simulated_laser_sees_a_new_wall() -> None:
    changes = plan_changes(2)
    x0, y0, x1, y1 = changes.walls[-1]  # the partition (the first is the closed door)
    world = changed_demo_world(changes)
    across = (x1 - x0) > (y1 - y0)
    start = ((x0 + x1) / 2, y0 - 1.0) if across else (x0 - 1.0, (y0 + y1) / 2)
    angle = math.pi / 2 if across else 0.0
    hits = world.cast(*start, np.array([angle]), 8.0)
    assert abs(hits.distance[0] - 1.0) < 0.06
