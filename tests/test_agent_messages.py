"""The robot's messages, the commands it reads, and how ``python -m robots.agent`` is told
where the server is and which robots to run."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from cloudnav_core.messages import (
    GoalStatus,
    StatusEntry,
    goal_of,
    initial_pose_of,
    path_message,
    pose_of,
    published_pose_of,
    status_array,
    twist_of,
    yaw_of,
)
from robots.agent.__main__ import arguments, tokens_of
from robots.agent.client import endpoints
from robots.agent.fleet import parse_pose


def test_a_path_faces_along_its_segments():
    path = path_message("b/M", [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0)], 5.0)
    assert path["header"]["frame_id"] == "b/M"
    yaws = [yaw_of(p["pose"]["orientation"]) for p in path["poses"]]
    assert yaws == pytest.approx([0.0, math.pi / 2, math.pi / 2])
    assert path_message("b/M", [], 0.0)["poses"] == []


def test_statuses_are_written_as_actionlib_writes_them():
    entry = StatusEntry("goal_1", 1.5, GoalStatus.PREEMPTED, "cancelled")
    written = status_array([entry], 2.0)
    assert written["status_list"] == [
        {
            "goal_id": {"stamp": {"sec": 1, "nanosec": 500_000_000}, "id": "goal_1"},
            "status": 2,
            "text": "cancelled",
        }
    ]
    assert GoalStatus.SUCCEEDED.terminal
    assert not GoalStatus.ACTIVE.terminal


def test_a_twist_is_read_and_a_broken_one_ignored():
    assert twist_of({"linear": {"x": 0.3}, "angular": {"z": -1}}) == (0.3, -1.0)
    assert twist_of({}) == (0.0, 0.0)
    assert twist_of({"linear": {"x": "fast"}}) is None
    assert twist_of({"linear": {"x": math.inf}}) is None
    assert twist_of({"linear": 3}) is None


def test_a_goal_needs_a_frame_and_a_finite_pose():
    pose = {"position": {"x": 1, "y": 2}, "orientation": {"z": 0, "w": 1}}
    goal = goal_of({"header": {"frame_id": "b/M"}, "pose": pose})
    assert goal is not None
    assert (goal.map_id, goal.x, goal.y, goal.yaw) == ("b/M", 1.0, 2.0, 0.0)
    assert goal_of({"header": {"frame_id": ""}, "pose": pose}) is None
    assert goal_of({"header": {"frame_id": "b/M"}}) is None


def test_an_initial_pose_keeps_its_planar_covariance_or_gets_a_default():
    covariance = np.zeros(36)
    covariance[[0, 7, 35]] = [0.01, 0.02, 0.03]
    pose = {"position": {"x": 1, "y": 2}, "orientation": {"w": 1}}
    msg = {"header": {"frame_id": "b/M"}, "pose": {"pose": pose, "covariance": covariance.tolist()}}
    found = initial_pose_of(msg)
    assert found is not None
    assert np.diag(found[1]) == pytest.approx([0.01, 0.02, 0.03])
    without = initial_pose_of({"header": {"frame_id": "b/M"}, "pose": {"pose": pose}})
    assert without is not None
    assert np.all(np.diag(without[1]) > 0)
    assert initial_pose_of({"header": {"frame_id": "b/M"}}) is None


@pytest.mark.parametrize(
    ("server", "http", "ws"),
    [
        ("http://127.0.0.1:8000", "http://127.0.0.1:8000", "ws://127.0.0.1:8000/rosbridge"),
        ("https://cloud.example", "https://cloud.example", "wss://cloud.example/rosbridge"),
        ("ws://h:1/rosbridge", "http://h:1", "ws://h:1/rosbridge"),
        ("ws://h:1", "http://h:1", "ws://h:1/rosbridge"),
        ("h:1", "http://h:1", "ws://h:1/rosbridge"),
    ],
)
def test_the_server_may_be_named_by_either_url(server, http, ws):
    assert endpoints(server) == (http, ws)


def test_a_start_pose_is_three_numbers():
    assert parse_pose("1,2.5,-3") == (1.0, 2.5, -3.0)
    for text in ("1,2", "a,b,c", "1,2,nan"):
        with pytest.raises(ValueError, match="not x,y,yaw"):
            parse_pose(text)


def test_robots_come_from_a_token_or_from_the_tokens_file(tmp_path: Path):
    tokens = tmp_path / "tokens.json"
    tokens.write_text(json.dumps({"robot_0": "t0", "robot_1": "t1"}))
    assert tokens_of(arguments(["--server", "h:1", "--token", "t"])) == [("robot", "t")]
    many = arguments(["--server", "h:1", "--tokens-file", str(tokens), "--count", "2"])
    assert tokens_of(many) == [("robot_0", "t0"), ("robot_1", "t1")]
    with pytest.raises(SystemExit):
        tokens_of(arguments(["--server", "h:1", "--tokens-file", str(tokens), "--count", "3"]))
    with pytest.raises(SystemExit):
        arguments(["--server", "h:1", "--token", "t", "--time-scale", "0"])


def test_a_published_pose_is_parsed_once_for_every_reader_of_that_message() -> None:
    msg = {
        "header": {"frame_id": "b/F"},
        "pose": {"position": {"x": 1.0, "y": 2.0}, "orientation": {"z": 0.0, "w": 1.0}},
    }
    first = published_pose_of(msg)
    assert first == pose_of(msg)
    assert published_pose_of(msg) is first  # the same message: the same answer, not parsed
    other = {**msg, "pose": {"position": {"x": 3.0, "y": 2.0}}}
    assert published_pose_of(other) == pose_of(other) != first
    assert published_pose_of({"pose": None}) is None
