"""``/cloudnav/plan_path``: the robot agent's global planner, offered by the cloud."""

from __future__ import annotations

import pytest

from maps import services as map_services
from maps.domain.planning import plan_path
from maps.models import SubMap
from tests.conftest import make_robot

pytestmark = pytest.mark.django_db(transaction=True)

CORRIDOR_A = "boccioni_1/CorridorA"
START, GOAL = {"x": 5.0, "y": 23.2}, {"x": 16.0, "y": 22.6}


def planned_here(map_code: str, start: dict, goal: dict) -> list[tuple[float, float]]:
    """What the domain planner gives for the same request, computed in the test."""
    submap = SubMap.objects.get(building__code="boccioni_1", code=map_code)
    grid = map_services.grid_of(submap)
    origin = (submap.origin_x, submap.origin_y)
    return plan_path(grid, (start["x"], start["y"]), (goal["x"], goal["y"]), 0.05, origin)


async def test_it_plans_as_the_agents_planner_does(rosbridge, demo_token):
    from asgiref.sync import sync_to_async

    robot = await rosbridge(token=demo_token)
    answer = await robot.call(
        "/cloudnav/plan_path", {"map_id": CORRIDOR_A, "start": START, "goal": GOAL}
    )
    assert answer["result"] is True
    path = answer["values"]["path"]
    assert path["header"]["frame_id"] == CORRIDOR_A
    points = [(p["pose"]["position"]["x"], p["pose"]["position"]["y"]) for p in path["poses"]]
    assert points == await sync_to_async(planned_here)("CorridorA", START, GOAL)
    assert answer["values"]["length"] == pytest.approx(11.0, abs=0.8)


async def test_a_goal_off_the_map_or_in_a_wall_fails_the_call(rosbridge, demo_token):
    robot = await rosbridge(token=demo_token)
    for goal in ({"x": 100.0, "y": 0.0}, {"x": 10.0, "y": 20.8}):  # off; behind a wall
        answer = await robot.call(
            "cloudnav/plan_path", {"map_id": CORRIDOR_A, "start": START, "goal": goal}
        )
        assert answer["result"] is False
        assert "goal" in answer["values"]


async def test_bad_arguments_fail_the_call(rosbridge, demo_token):
    robot = await rosbridge(token=demo_token)
    for args in (
        {"map_id": CORRIDOR_A, "start": START},
        {"map_id": CORRIDOR_A, "start": {"x": "a"}, "goal": GOAL},
        {"map_id": CORRIDOR_A, "start": START, "goal": GOAL, "robot_radius": -1},
    ):
        answer = await robot.call("/cloudnav/plan_path", args)
        assert answer["result"] is False


async def test_it_rejects_outsider(rosbridge, demo_token):
    from asgiref.sync import sync_to_async

    stranger = (await sync_to_async(make_robot)(name="stranger"))[1]  # in no building
    robot = await rosbridge(token=stranger)
    answer = await robot.call(
        "/cloudnav/plan_path", {"map_id": CORRIDOR_A, "start": START, "goal": GOAL}
    )
    assert answer["result"] is False
    assert "not a visible sub-map" in answer["values"]
