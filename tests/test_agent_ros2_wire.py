"""NavigateToPose on the wire, Humble to Kilted: CDR from ``rosbags``' type stores
(``ROS2_HUMBLE``, ``ROS2_JAZZY``, ``ROS2_KILTED``) against what the bridge writes and reads
through stock rclpy (the Jazzy and Kilted virtualenvs of ``scripts/ros2_env.sh``).

The goal and feedback are the same bytes in every distro; the result is not (Humble's
``std_msgs/Empty result``, Jazzy and Kilted's ``error_code`` and ``error_msg``), and the
bridge reads only the status in front of it, which sits at the same offset in all three.
No Humble wheels exist, so Humble is proven here on the bytes alone.
"""

from __future__ import annotations

import json
import subprocess
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from benchmarks.agent import ROOT
from benchmarks.ros2_bridge import graph_env

GOAL = """geometry_msgs/PoseStamped pose
string behavior_tree"""
FEEDBACK = """geometry_msgs/PoseStamped current_pose
builtin_interfaces/Duration navigation_time
builtin_interfaces/Duration estimated_time_remaining
int16 number_of_recoveries
float32 distance_remaining"""
RESULTS = {
    Stores.ROS2_HUMBLE: "std_msgs/Empty result",
    Stores.ROS2_JAZZY: "uint16 error_code\nstring error_msg",
    Stores.ROS2_KILTED: "uint16 error_code\nstring error_msg",
}
STORES = list(RESULTS)
UUID = list(range(1, 17))
POSE = (1.5, -2.0, 0.3)  # what the bridge sends, in the map frame
SUCCEEDED = 4  # action_msgs/GoalStatus.STATUS_SUCCEEDED
RESULT = "nav2_msgs/msg/NavigateToPose_GetResult_Response"

# Run in the ROS 2 virtualenv: the bridge's own goal, feedback reading and result reading
# on rclpy's bytes. Reads {"feedback": hex, "results": {name: hex}}; writes the answers.
ROBOT_SIDE = """
import json, sys
from builtin_interfaces.msg import Time
from nav2_msgs.action import NavigateToPose
from rclpy.serialization import deserialize_message, serialize_message
from robots.agent.ros2.navigation import navigate_goal, progress_of, state_of_result

asked = json.load(sys.stdin)
impl = NavigateToPose.Impl
request = impl.SendGoalService.Request()
request.goal_id.uuid = list(range(1, 17))
request.goal = navigate_goal("map", (1.5, -2.0, 0.3), Time(sec=12, nanosec=5))
feedback = deserialize_message(bytes.fromhex(asked["feedback"]), impl.FeedbackMessage)
answers = {
    name: deserialize_message(bytes.fromhex(data), impl.GetResultService.Response)
    for name, data in asked["results"].items()
}
print(json.dumps({
    "goal": serialize_message(request).hex(),
    "progress": progress_of(feedback.feedback),
    "feedback": serialize_message(feedback).hex(),
    "states": {name: state_of_result(answer).value for name, answer in answers.items()},
    "results": {name: serialize_message(answer).hex() for name, answer in answers.items()},
}))
"""


def nav2_store(store: Stores) -> Any:
    """``store`` with NavigateToPose's goal, feedback, result and their action wrappers."""
    typestore = get_typestore(store)
    wrappers = {
        "NavigateToPose_Goal": GOAL,
        "NavigateToPose_Feedback": FEEDBACK,
        "NavigateToPose_Result": RESULTS[store],
        "NavigateToPose_SendGoal_Request": "unique_identifier_msgs/UUID goal_id\n"
        "nav2_msgs/NavigateToPose_Goal goal",
        "NavigateToPose_FeedbackMessage": "unique_identifier_msgs/UUID goal_id\n"
        "nav2_msgs/NavigateToPose_Feedback feedback",
        "NavigateToPose_GetResult_Response": "int8 status\nnav2_msgs/NavigateToPose_Result result",
    }
    for name, text in wrappers.items():
        typestore.register(get_types_from_msg(text, f"nav2_msgs/msg/{name}"))
    return typestore


def goal_bytes(store: Stores) -> bytes:
    t = nav2_store(store)
    types = t.types
    header = types["std_msgs/msg/Header"](types["builtin_interfaces/msg/Time"](12, 5), "map")
    q = types["geometry_msgs/msg/Quaternion"](0.0, 0.0, np.sin(POSE[2] / 2), np.cos(POSE[2] / 2))
    point = types["geometry_msgs/msg/Point"](POSE[0], POSE[1], 0.0)
    stamped = types["geometry_msgs/msg/PoseStamped"](
        header, types["geometry_msgs/msg/Pose"](point, q)
    )
    goal = types["nav2_msgs/msg/NavigateToPose_Goal"](stamped, "")
    uuid = types["unique_identifier_msgs/msg/UUID"](np.array(UUID, dtype=np.uint8))
    request = types["nav2_msgs/msg/NavigateToPose_SendGoal_Request"](uuid, goal)
    return bytes(t.serialize_cdr(request, "nav2_msgs/msg/NavigateToPose_SendGoal_Request"))


def feedback_bytes(store: Stores) -> bytes:
    t = nav2_store(store)
    types = t.types
    duration = types["builtin_interfaces/msg/Duration"]
    header = types["std_msgs/msg/Header"](types["builtin_interfaces/msg/Time"](3, 0), "map")
    q = types["geometry_msgs/msg/Quaternion"](0.0, 0.0, 0.0, 1.0)
    pose = types["geometry_msgs/msg/Pose"](types["geometry_msgs/msg/Point"](1.0, 2.0, 0.0), q)
    feedback = types["nav2_msgs/msg/NavigateToPose_Feedback"](
        types["geometry_msgs/msg/PoseStamped"](header, pose),
        duration(4, 0),
        duration(9, 0),
        2,
        3.25,
    )
    uuid = types["unique_identifier_msgs/msg/UUID"](np.array(UUID, dtype=np.uint8))
    message = types["nav2_msgs/msg/NavigateToPose_FeedbackMessage"](uuid, feedback)
    return bytes(t.serialize_cdr(message, "nav2_msgs/msg/NavigateToPose_FeedbackMessage"))


def result_bytes(store: Stores, status: int) -> bytes:
    t = nav2_store(store)
    types = t.types
    if store is Stores.ROS2_HUMBLE:
        result = types["nav2_msgs/msg/NavigateToPose_Result"](types["std_msgs/msg/Empty"]())
    else:
        result = types["nav2_msgs/msg/NavigateToPose_Result"](
            0 if status == SUCCEEDED else 9000, ""
        )
    answer = types["nav2_msgs/msg/NavigateToPose_GetResult_Response"](status, result)
    return bytes(t.serialize_cdr(answer, "nav2_msgs/msg/NavigateToPose_GetResult_Response"))


def same_layout(ours: bytes, theirs: bytes, store: Stores, name: str) -> bool:
    """Whether ``ours`` are ``theirs`` but for padding: Fast CDR leaves padding bytes as
    it found them, rosbags writes zeros; each parses the other's to the same values."""
    typestore = nav2_store(store)
    again = bytes(typestore.serialize_cdr(typestore.deserialize_cdr(ours, name), name))
    return len(ours) == len(theirs) and again == theirs


def robot_side(env: dict[str, str], asked: dict[str, Any]) -> dict[str, Any]:
    """What the bridge's code makes of ``asked`` through rclpy (``ROBOT_SIDE``)."""
    ran = subprocess.run(
        ["python", "-c", ROBOT_SIDE],
        input=json.dumps(asked),
        env=env,
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert ran.returncode == 0, ran.stderr[-3000:]
    answer: dict[str, Any] = json.loads(ran.stdout.strip().splitlines()[-1])
    return answer


@pytest.fixture(scope="module")
def answered(ros2_venv: Path) -> dict[str, Any]:
    """The robot side's answers to Jazzy's feedback and to a succeeded and an aborted
    result of its own distro's layout (Jazzy and Kilted share it)."""
    results = {
        "succeeded": result_bytes(Stores.ROS2_JAZZY, SUCCEEDED).hex(),
        "aborted": result_bytes(Stores.ROS2_JAZZY, 6).hex(),
        "canceled": result_bytes(Stores.ROS2_JAZZY, 5).hex(),
    }
    return robot_side(
        graph_env(ros2_venv),
        {"feedback": feedback_bytes(Stores.ROS2_JAZZY).hex(), "results": results},
    )


@pytest.mark.slow  # the ROS 2 virtualenv (built on first use) and rclpy in a subprocess
@pytest.mark.parametrize("store", STORES, ids=lambda s: s.name)
def test_the_goal_the_bridge_sends_is_byte_for_byte_each_distros(
    answered: dict[str, Any], store: Stores
) -> None:
    assert bytes.fromhex(answered["goal"]) == goal_bytes(store)


@pytest.mark.slow
@pytest.mark.parametrize("store", STORES, ids=lambda s: s.name)
def test_the_bridge_reads_each_distros_feedback(answered: dict[str, Any], store: Stores) -> None:
    ours, theirs = bytes.fromhex(answered["feedback"]), feedback_bytes(store)
    assert same_layout(ours, theirs, store, "nav2_msgs/msg/NavigateToPose_FeedbackMessage")
    assert answered["progress"] == "Nav2: 3.2 m to go, 2 recoveries"


@pytest.mark.slow
def test_the_bridge_reads_jazzy_and_kilted_results_by_their_status(
    answered: dict[str, Any],
) -> None:
    assert answered["states"] == {"succeeded": "succeeded", "aborted": "failed", "canceled": "none"}
    for status, name in ((SUCCEEDED, "succeeded"), (6, "aborted")):
        for store in (Stores.ROS2_JAZZY, Stores.ROS2_KILTED):
            ours, theirs = bytes.fromhex(answered["results"][name]), result_bytes(store, status)
            assert same_layout(ours, theirs, store, RESULT)


def test_humbles_result_differs_after_the_status_the_bridge_reads() -> None:
    humble, jazzy = (
        result_bytes(Stores.ROS2_HUMBLE, SUCCEEDED),
        result_bytes(Stores.ROS2_JAZZY, SUCCEEDED),
    )
    # CDR header, then the int8 status: the same bytes; the result after it is not.
    assert humble[:5] == jazzy[:5]
    assert humble[4] == SUCCEEDED
    assert humble[5:] != jazzy[5:]
    typestore = nav2_store(Stores.ROS2_HUMBLE)
    answer = typestore.deserialize_cdr(humble, "nav2_msgs/msg/NavigateToPose_GetResult_Response")
    assert answer.status == SUCCEEDED
    assert answer.result.result.__msgtype__ == "std_msgs/msg/Empty"
