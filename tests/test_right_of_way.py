"""Right of way in narrow places (issue 28, point 2), the arbiter alone: no Django, the
demo building's real grid. Corridor A's entrance door (x 3.6 to 3.8, 1.2 m wide) joins
the porch and the corridor (2.4 m wide) inside one sub-map."""

from __future__ import annotations

import math

import pytest

from cloudnav_core.se2 import Point
from maps.domain.demo_building import demo_building
from maps.domain.right_of_way import CROSSING_REACH, Arbiter, Verdict, narrow_stretches
from maps.domain.topology import approach_pose
from maps.domain.widths import Widths

RADIUS = 0.25  # the planner's footprint: body 0.18 m plus margin 0.07 m
MAP = "boccioni_1/CorridorA"
DOOR_X = (3.6, 3.8)


class Clock:
    def __init__(self) -> None:
        self.now = 0.0

    def __call__(self) -> float:
        return self.now


@pytest.fixture(scope="module")
def widths() -> Widths:
    building = demo_building()
    return Widths.of_grid(building.world, building.world_origin, building.resolution)


def line(a: Point, b: Point, step: float = 0.05) -> list[Point]:
    n = max(1, int(math.dist(a, b) / step))
    return [(a[0] + (b[0] - a[0]) * k / n, a[1] + (b[1] - a[1]) * k / n) for k in range(n + 1)]


EAST = line((2.4, 23.8), (7.0, 23.8))  # from the porch into the corridor
WEST = line((7.0, 23.8), (2.4, 23.8))  # from the corridor out to the porch


def waits(verdicts: list[Verdict]) -> dict[str, str]:
    return {v.robot: v.waiting_for for v in verdicts if v.waits}


def waiting_for(arbiter: Arbiter, robot: str) -> str:
    verdict = arbiter.verdict(robot)
    assert verdict is not None
    return verdict.waiting_for


def test_the_door_is_narrow_and_the_corridor_is_not(widths):
    arbiter = Arbiter(RADIUS)
    [(first, last)] = narrow_stretches(EAST, widths, arbiter.narrower_than)
    assert DOOR_X[0] - 0.3 <= EAST[first][0] <= DOOR_X[0]
    assert DOOR_X[1] <= EAST[last][0] <= DOOR_X[1] + 0.3
    along_corridor = line((5.0, 22.6), (15.0, 22.6))
    assert narrow_stretches(along_corridor, widths, arbiter.narrower_than) == []


def test_two_robots_one_door_the_first_to_ask_goes_and_the_other_waits_clear_of_it(widths):
    clock = Clock()
    arbiter = Arbiter(RADIUS, clock)
    arbiter.route("a", MAP, EAST, widths)
    arbiter.at("a", MAP, (2.6, 23.8))  # 1 m from the door: asks now
    arbiter.route("b", MAP, WEST, widths)
    arbiter.at("b", MAP, (8.0, 23.8))  # past the end of its route's start: too far to ask
    assert arbiter.decide() == []
    assert arbiter.holder("a") is not None
    clock.now = 1.0
    arbiter.at("b", MAP, (5.5, 23.8))  # 1.7 m from the door: asks, a holds it
    [told] = arbiter.decide()
    assert (told.robot, told.waiting_for) == ("b", "a")
    assert told.spot is not None
    assert told.place is not None
    spot = told.spot[:2]
    assert math.dist(spot, told.place) >= RADIUS + 0.3  # out of the narrow part
    assert min(math.dist(spot, p) for p in EAST) >= 2 * RADIUS + 0.3  # clear of a's route
    assert spot[0] > DOOR_X[1]  # on b's side of the door
    assert "b waits at" in told.describe()
    assert "for a to pass" in told.describe()
    # a goes through; once past, b may go
    arbiter.at("a", MAP, (3.7, 23.8))
    assert arbiter.decide() == []
    arbiter.at("a", MAP, (4.6, 23.8))
    [go] = arbiter.decide()
    assert (go.robot, go.waits) == ("b", False)
    assert arbiter.holder("b") is not None


def test_three_robots_take_the_door_in_the_order_they_asked(widths):
    clock = Clock()
    arbiter = Arbiter(RADIUS, clock)
    arbiter.route("a", MAP, EAST, widths)
    arbiter.at("a", MAP, (2.6, 23.8))
    arbiter.decide()
    clock.now = 1.0
    arbiter.route("b", MAP, WEST, widths)
    arbiter.at("b", MAP, (5.0, 23.8))
    arbiter.decide()
    clock.now = 2.0
    arbiter.route("c", MAP, line((6.0, 22.8), (2.4, 23.8)), widths)
    arbiter.at("c", MAP, (6.0, 22.8))
    assert waits(arbiter.decide()) == {"c": "a"}
    arbiter.at("a", MAP, (5.5, 24.0))  # a through and away: b asked before c
    arbiter.decide()
    assert arbiter.holder("b") is not None
    assert waiting_for(arbiter, "c") == "b"
    arbiter.at("b", MAP, (2.4, 23.8))  # b through
    arbiter.decide()
    assert arbiter.holder("c") is not None


def test_a_robot_that_asks_later_never_overtakes_one_waiting(widths):
    clock = Clock()
    arbiter = Arbiter(RADIUS, clock)
    arbiter.route("a", MAP, EAST, widths)
    arbiter.at("a", MAP, (3.0, 23.8))
    arbiter.decide()
    clock.now = 1.0
    arbiter.route("b", MAP, WEST, widths)
    arbiter.at("b", MAP, (6.0, 23.8))  # waits, 2.2 m from the door
    arbiter.decide()
    for t in range(2, 30):  # robots keep coming from the porch, each nearer than b
        clock.now = float(t)
        name = f"p{t}"
        arbiter.route(name, MAP, EAST, widths)
        arbiter.at(name, MAP, (2.8, 23.8))
        arbiter.decide()
        assert arbiter.holder(name) is None
        arbiter.leave(name)
    arbiter.at("a", MAP, (5.0, 22.8))
    arbiter.route("late", MAP, EAST, widths)
    arbiter.at("late", MAP, (2.9, 23.8))  # nearer the door than b, but asked after it
    arbiter.decide()
    assert arbiter.holder("b") is not None
    assert arbiter.holder("late") is None
    assert waiting_for(arbiter, "late") == "b"


def test_in_a_wide_place_nobody_is_arbitrated(widths):
    arbiter = Arbiter(RADIUS)
    # head on along Corridor A (2.4 m wide), and across Atrium 1
    arbiter.route("a", MAP, line((5.0, 23.2), (15.0, 23.2)), widths)
    arbiter.at("a", MAP, (9.0, 23.2))
    arbiter.route("b", MAP, line((15.0, 23.2), (5.0, 23.2)), widths)
    arbiter.at("b", MAP, (11.0, 23.2))
    atrium = "boccioni_1/Atrium1"
    arbiter.route("c", atrium, line((19.0, 20.0), (25.0, 26.5)), widths)
    arbiter.at("c", atrium, (21.0, 22.0))
    arbiter.route("d", atrium, line((25.0, 20.0), (19.0, 26.5)), widths)
    arbiter.at("d", atrium, (23.0, 22.0))
    assert arbiter.decide() == []
    assert all(arbiter.passages(r) == [] for r in "abcd")


def test_robots_in_different_sub_maps_never_wait_for_each_other(widths):
    arbiter = Arbiter(RADIUS)
    arbiter.route("a", MAP, EAST, widths)
    arbiter.at("a", MAP, (2.6, 23.8))
    arbiter.route("b", "boccioni_1/Elsewhere", WEST, widths)
    arbiter.at("b", "boccioni_1/Elsewhere", (4.5, 23.8))
    assert arbiter.decide() == []
    assert arbiter.holder("a") is not None
    assert arbiter.holder("b") is not None


def test_a_waiting_robots_plan_to_its_spot_keeps_its_route_and_its_turn(widths):
    clock = Clock()
    arbiter = Arbiter(RADIUS, clock)
    arbiter.route("a", MAP, EAST, widths)
    arbiter.at("a", MAP, (2.6, 23.8))
    arbiter.decide()
    arbiter.route("b", MAP, WEST, widths)
    arbiter.at("b", MAP, (5.0, 23.8))
    [told] = arbiter.decide()
    assert told.spot is not None
    arbiter.route("b", MAP, line((5.0, 23.8), told.spot[:2]), widths)  # the plan to its spot
    assert arbiter.passages("b") != []
    arbiter.at("a", MAP, (5.5, 24.0))
    [go] = arbiter.decide()
    assert (go.robot, go.waits) == ("b", False)


def test_a_robot_that_leaves_gives_the_door_up(widths):
    arbiter = Arbiter(RADIUS)
    arbiter.route("a", MAP, EAST, widths)
    arbiter.at("a", MAP, (3.5, 23.8))
    arbiter.route("b", MAP, WEST, widths)
    arbiter.at("b", MAP, (5.0, 23.8))
    assert waits(arbiter.decide()) == {"b": "a"}
    arbiter.leave("a")
    [go] = arbiter.decide()
    assert (go.robot, go.waits) == ("b", False)


def test_robots_crossing_at_one_tag_read_it_one_at_a_time(widths):
    # Tag 1 stands at Corridor A's east end, beside the door to Atrium 1 (wide there):
    # two robots heading to read it are arbitrated as at a door, the second waiting clear
    # of the first until it has entered Atrium 1, instead of crowding round the tag.
    tag_1 = next(t for t in demo_building().tags if t.marker_id == 1)
    reading = approach_pose((tag_1.x, tag_1.y, tag_1.yaw))[:2]
    crossings = [reading]
    clock = Clock()
    arbiter = Arbiter(RADIUS, clock)
    route_a = line((13.0, 23.2), reading)
    arbiter.route("a", MAP, route_a, widths, crossings)
    [passage] = arbiter.passages("a")
    assert passage.last == len(route_a) - 1
    assert math.dist(route_a[passage.first], reading) == pytest.approx(CROSSING_REACH, abs=0.06)
    arbiter.route("a", MAP, route_a, widths)  # the same route with no crossing known
    assert arbiter.passages("a") == []
    arbiter.route("a", MAP, route_a, widths, crossings)
    arbiter.at("a", MAP, (15.0, 23.0))
    assert arbiter.decide() == []
    assert arbiter.holder("a") is not None
    clock.now = 1.0
    route_b = line((12.0, 22.0), reading)
    arbiter.route("b", MAP, route_b, widths, crossings)
    arbiter.at("b", MAP, (14.5, 22.2))
    [told] = arbiter.decide()
    assert (told.robot, told.waiting_for) == ("b", "a")
    assert told.spot is not None
    assert math.dist(told.spot[:2], reading) >= RADIUS
    arbiter.at("a", "boccioni_1/Atrium1", (18.5, 22.6))  # a read the tag: it is in Atrium 1
    [go] = arbiter.decide()
    assert (go.robot, go.waits) == ("b", False)
    assert arbiter.holder("b") is not None
