"""Unmodified roslibpy (from PyPI) against the live server.

roslibpy runs Twisted's reactor in a thread of its own and cannot restart it, so each
scenario runs in a fresh Python process: ``python -m tests.test_rosbridge_roslibpy NAME
ARGS_JSON`` prints the scenario's findings as JSON, and the tests below assert on them.
This module imports nothing from Django at the top, so that process stays a plain client.
"""

from __future__ import annotations

import json
import sys
import threading
from pathlib import Path
from typing import Any

import pytest

ROOT = Path(__file__).resolve().parent.parent
WAIT = 10.0
POSE = {"header": {"frame_id": "boccioni_1/Hall"}, "pose": {"position": {"x": 1.0, "y": 2.0}}}


# ---------------------------------------------------------------- the client side


def _connect(args: dict[str, Any], who: str) -> Any:
    import roslibpy

    if who == "operator":
        headers = {"Cookie": args["cookie"], "Origin": args["origin"]}
        ros = roslibpy.Ros(args["url"], port=None, headers=headers)
    else:
        ros = roslibpy.Ros(f"{args['url']}?token={args['token']}", port=None)
    ros.run(timeout=WAIT)
    return ros


def collect(into: list[Any], item: Any, done: threading.Event) -> None:
    into.append(item)
    done.set()


def _wait(event: threading.Event, what: str) -> None:
    if not event.wait(WAIT):
        raise TimeoutError(f"no {what} within {WAIT} s")


def scenario_pubsub(args: dict[str, Any]) -> dict[str, Any]:
    """The operator subscribes to the robot's pose; the robot publishes it."""
    import roslibpy

    robot, operator = _connect(args, "robot"), _connect(args, "operator")
    received: list[Any] = []
    arrived = threading.Event()
    listener = roslibpy.Topic(operator, "/r1/pose", "geometry_msgs/PoseStamped")
    listener.subscribe(lambda message: collect(received, message, arrived))
    operator.get_time()  # the subscription is in place once this answers
    roslibpy.Topic(robot, "pose", "geometry_msgs/PoseStamped").publish(roslibpy.Message(POSE))
    _wait(arrived, "pose")
    return {"received": received[0]}


def scenario_rosapi(args: dict[str, Any]) -> dict[str, Any]:
    """rosapi calls through roslibpy's helpers: topics, services, nodes, time, params."""
    import roslibpy

    robot, operator = _connect(args, "robot"), _connect(args, "operator")
    roslibpy.Topic(robot, "map_id", "std_msgs/String").publish(roslibpy.Message({"data": "m"}))
    robot.get_time()
    roslibpy.Param(robot, "max_speed").set(0.5)
    time = operator.get_time()
    return {
        "topics": operator.get_topics(),
        "services": operator.get_services(),
        "nodes": operator.get_nodes(),
        "time": [time.secs, time.nsecs],
        "param": roslibpy.Param(operator, "/r1/max_speed").get(),
    }


def scenario_cloud_service(args: dict[str, Any]) -> dict[str, Any]:
    """The operator takes the robot's teleop lock through the cloud's own service."""
    import roslibpy

    operator = _connect(args, "operator")
    service = roslibpy.Service(operator, "/cloudnav/teleop_lock", "cloudnav/TeleopLock")
    response = service.call(roslibpy.ServiceRequest({"robot": "r1", "action": "acquire"}))
    return {"response": dict(response)}


def scenario_advertised_service(args: dict[str, Any]) -> dict[str, Any]:
    """The robot advertises and answers a service; the operator calls it."""
    import roslibpy

    robot, operator = _connect(args, "robot"), _connect(args, "operator")
    requests: list[Any] = []

    def dock(request: Any, response: Any) -> bool:
        requests.append(dict(request))
        response["success"] = True
        response["message"] = "docked"
        return True

    roslibpy.Service(robot, "dock", "std_srvs/SetBool").advertise(dock)
    robot.get_time()
    call = roslibpy.Service(operator, "/r1/dock", "std_srvs/SetBool")
    response = call.call(roslibpy.ServiceRequest({"data": True}), timeout=WAIT)
    return {"requests": requests, "response": dict(response)}


def scenario_action(args: dict[str, Any]) -> dict[str, Any]:
    """The operator sends a goal with roslibpy's ActionClient; a raw client serves it."""
    import roslibpy
    from websockets.sync.client import connect

    served = threading.Event()
    with connect(f"{args['url']}?token={args['token']}") as server:
        server.send(json.dumps({"op": "advertise_action", "action": "navigate", "type": "a/B"}))
        server.send(json.dumps({"op": "call_service", "id": "ok", "service": "/rosapi/get_time"}))
        json.loads(server.recv(WAIT))
        operator = _connect(args, "operator")
        client = roslibpy.ActionClient(operator, "/r1/navigate", "nav2_msgs/action/NavigateToPose")
        feedback: list[Any] = []
        results: list[Any] = []
        goal_id = client.send_goal(
            roslibpy.Goal({"pose": POSE}),
            lambda result: collect(results, dict(result), served),
            lambda message: feedback.append(dict(message)),
            lambda error: collect(results, {"error": str(error)}, served),
        )
        goal = json.loads(server.recv(WAIT))
        for frame in (
            {"op": "action_feedback", "values": {"distance_remaining": 2.0}},
            {"op": "action_result", "values": {"reached": True}, "status": 4, "result": True},
        ):
            server.send(json.dumps({**frame, "action": "/r1/navigate", "id": goal["id"]}))
        _wait(served, "action result")
    return {"goal": goal, "goal_id": goal_id, "feedback": feedback, "results": results}


def main() -> None:
    name, args = sys.argv[1], json.loads(sys.argv[2])
    print(json.dumps(globals()[f"scenario_{name}"](args), default=str), flush=True)


# ---------------------------------------------------------------- the tests


@pytest.fixture
def run(daphne_server, building, operator):
    from tests.fixtures_live import client_scenarios

    command = [sys.executable, "-m", "tests.test_rosbridge_roslibpy"]
    return client_scenarios(command, daphne_server, building, operator)


def test_roslibpy_subscribes_to_what_a_robot_publishes(run):
    assert run("pubsub")["received"] == POSE


def test_roslibpy_rosapi_helpers_work(run):
    found = run("rosapi")
    assert "/r1/map_id" in found["topics"]
    assert "/cloudnav/teleop_lock" in found["services"]
    assert "/r1" in found["nodes"]
    assert found["time"][0] > 1_700_000_000
    assert found["param"] == 0.5


def test_roslibpy_calls_a_cloud_service(run):
    assert run("cloud_service")["response"] == {
        "success": True,
        "holder": "user:operator",
        "message": "",
    }


def test_roslibpy_advertises_and_answers_a_service(run):
    found = run("advertised_service")
    assert found["requests"] == [{"data": True}]
    assert found["response"] == {"success": True, "message": "docked"}


def test_roslibpy_sends_an_action_goal_and_gets_feedback(run):
    found = run("action")
    assert found["goal"]["op"] == "send_action_goal"
    assert found["goal"]["args"] == {"pose": POSE}
    assert found["feedback"] == [{"distance_remaining": 2.0}]
    assert found["results"][0]["values"] == {"reached": True}


if __name__ == "__main__":
    main()
