"""Nav2 fed by the Maps Supervisor (``NavigationStack``), on stock rclpy: the sub-map on
``/map`` with transient-local QoS (as Nav2's map_server publishes it, so a late AMCL or
costmap still gets it) and, where configured, in map-server files that Nav2's map_server
loads through its ``nav2_msgs/LoadMap`` service (``/map_server/load_map``); the tag's pose
on ``/initialpose`` with its covariance; each leg a ``nav2_msgs/NavigateToPose`` goal on
``navigate_to_pose``, its feedback kept for ``nav_status``, cancel through the action. The
pose comes from AMCL's ``/amcl_pose`` or from tf (``map -> base_footprint``), the plan
from the planner server's ``/plan``. Spin the node in another thread."""

from __future__ import annotations

import array
import logging
import math
import threading
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from action_msgs.msg import GoalStatus  # type: ignore[import-not-found,unused-ignore]
from geometry_msgs.msg import PoseWithCovarianceStamped  # type: ignore[import-not-found,unused-ignore]
from nav2_msgs.action import NavigateToPose  # type: ignore[import-not-found,unused-ignore]
from nav2_msgs.srv import LoadMap  # type: ignore[import-not-found,unused-ignore]
from nav_msgs.msg import OccupancyGrid  # type: ignore[import-not-found,unused-ignore]
from nav_msgs.msg import Path as RosPath  # type: ignore[import-not-found,unused-ignore]
from numpy.typing import NDArray
from rclpy.action import ActionClient  # type: ignore[import-not-found,unused-ignore]
from rclpy.node import Node  # type: ignore[import-not-found,unused-ignore]
from rclpy.qos import (  # type: ignore[import-not-found,unused-ignore]
    DurabilityPolicy,
    QoSProfile,
    ReliabilityPolicy,
)

from cloudnav_core.se2 import Point, Pose, compose
from robots.agent.bridge import (
    StackReadings,
    load_map_files,
    plan_of,
    pose_of,
    pose_of_transform,
    set_pose,
    write_grid_info,
    write_initial_pose,
)
from robots.agent.hardware import StackGoal
from robots.agent.ros2 import stamp_seconds

logger = logging.getLogger(__name__)

LATCHED = QoSProfile(
    depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL, reliability=ReliabilityPolicy.RELIABLE
)
"""Nav2's map QoS: a subscriber that comes later still gets the last map."""
STATES = {
    GoalStatus.STATUS_SUCCEEDED: StackGoal.SUCCEEDED,
    GoalStatus.STATUS_CANCELED: StackGoal.NONE,
    GoalStatus.STATUS_ABORTED: StackGoal.FAILED,
}
"""A finished goal's status as the Maps Supervisor's driver needs it (others: ACTIVE)."""
SERVER_WAIT = 30.0
"""Seconds a goal waits for the action server (or a map for ``LoadMap``) to appear."""


def navigate_goal(frame: str, pose: Pose, stamp: Any) -> Any:
    """The ``NavigateToPose`` goal to ``pose`` in ``frame`` (Nav2's default tree)."""
    goal = NavigateToPose.Goal()
    goal.pose.header.stamp = stamp
    goal.pose.header.frame_id = frame
    set_pose(goal.pose.pose, pose)
    return goal


def state_of_result(answer: Any) -> StackGoal:
    """How a goal ended, from the action's ``GetResult`` answer (None: no answer). Only
    its status is read: the result differs by distro (Humble's ``std_msgs/Empty``, Jazzy
    and Kilted's ``error_code`` and ``error_msg``)."""
    status = GoalStatus.STATUS_UNKNOWN if answer is None else answer.status
    return STATES.get(status, StackGoal.FAILED)


def progress_of(feedback: Any) -> str:
    """``nav_status`` text of a ``NavigateToPose`` feedback (its Humble to Kilted fields)."""
    return (
        f"Nav2: {feedback.distance_remaining:.1f} m to go, "
        f"{feedback.number_of_recoveries} recoveries"
    )


class TransformChain:
    """The planar transforms of ``/tf`` and ``/tf_static``, child to parent, and the
    pose of one frame in another along them."""

    def __init__(self) -> None:
        self._parents: dict[str, tuple[str, Pose, float]] = {}
        self._lock = threading.Lock()

    def on_message(self, msg: Any) -> None:
        with self._lock:
            for seen in msg.transforms:
                pose = pose_of_transform(seen.transform)
                stamp = stamp_seconds(seen.header.stamp)
                self._parents[seen.child_frame_id] = (seen.header.frame_id, pose, stamp)

    def lookup(self, frame: str, child: str) -> tuple[float, Pose] | None:
        """(stamp, pose of ``child`` in ``frame``); None if tf does not link them. The
        stamp is the oldest of the moving transforms on the way (static ones are 0)."""
        pose, stamp, here = (0.0, 0.0, 0.0), math.inf, child
        with self._lock:
            for _ in range(len(self._parents) + 1):
                if here == frame:
                    return (stamp if math.isfinite(stamp) else 0.0, pose)
                if here not in self._parents:
                    return None
                here, step, seen = self._parents[here]
                pose, stamp = compose(step, pose), min(stamp, seen) if seen > 0 else stamp
        return None


class Nav2Stack:
    """``/map``, ``/initialpose``, ``navigate_to_pose`` and ``LoadMap`` of one robot; the
    frame of every pose is ``frame`` (the map frame). ``pose_source`` is ``amcl_pose`` (or
    any ``PoseWithCovarianceStamped`` topic) or ``tf`` (``frame -> base_frame``);
    ``load_map`` a ``nav2_msgs/LoadMap`` service whose map files go under ``map_dir``, or
    None. ``loaded`` lists (seconds on the monotonic clock, result) of its answers."""

    def __init__(
        self,
        node: Node,
        frame: str = "map",
        map_topic: str = "/map",
        initial_pose_topic: str = "/initialpose",
        action: str = "navigate_to_pose",
        pose_source: str = "amcl_pose",
        base_frame: str = "base_footprint",
        plan_topic: str = "/plan",
        load_map: str | None = None,
        map_dir: Path | None = None,
    ) -> None:
        self._node, self.frame, self.base_frame = node, frame, base_frame
        self.readings = StackReadings()
        self.loaded: list[tuple[float, int]] = []
        self._map = node.create_publisher(OccupancyGrid, map_topic, LATCHED)
        self._initial = node.create_publisher(
            PoseWithCovarianceStamped, initial_pose_topic, LATCHED
        )
        self._action = ActionClient(node, NavigateToPose, action)
        self._lock = threading.Lock()
        self._goal = 0  # the number of the latest goal sent
        self._state = StackGoal.NONE
        self._handle: Any = None
        self._cancel_asked = False
        self._tf: TransformChain | None = None
        if pose_source == "tf":
            self._tf = TransformChain()
            node.create_subscription(_tf_message(), "/tf", self._tf.on_message, 100)
            node.create_subscription(_tf_message(), "/tf_static", self._tf.on_message, LATCHED)
        else:
            node.create_subscription(PoseWithCovarianceStamped, pose_source, self._on_pose, 10)
        node.create_subscription(RosPath, plan_topic, self._on_plan, 10)
        self._load_map = node.create_client(LoadMap, load_map) if load_map else None
        self._map_dir = map_dir

    @property
    def map_id(self) -> str | None:
        return self.readings.map_id

    # --- maps and poses ----------------------------------------------------------------

    def set_map(self, map_id: str, grid: Any, resolution: float, origin: Pose) -> None:
        cells = np.asarray(grid, dtype=np.int8)
        msg = OccupancyGrid()
        msg.header.stamp, msg.header.frame_id = self._now(), self.frame
        msg.info.map_load_time = msg.header.stamp
        write_grid_info(msg, cells, resolution, origin)
        msg.data = array.array("b", cells.tobytes())
        self.readings.map_id = map_id
        self._map.publish(msg)
        ask = None if self._load_map is None else self._ask_map_server
        load_map_files(ask, self._map_dir, map_id, cells, resolution, origin)

    def _ask_map_server(self, url: str) -> None:
        """Call ``LoadMap`` (off the control loop); failures are logged."""
        assert self._load_map is not None
        if not self._load_map.wait_for_service(timeout_sec=SERVER_WAIT):
            logger.warning("load_map %s: no map server", url)
            return
        done = threading.Event()
        future = self._load_map.call_async(LoadMap.Request(map_url=url))
        future.add_done_callback(lambda _f: done.set())
        if not done.wait(SERVER_WAIT) or future.result() is None:
            logger.warning("load_map %s: no answer", url)
            return
        result = int(future.result().result)
        self.loaded.append((time.monotonic(), result))
        if result != LoadMap.Response.RESULT_SUCCESS:
            logger.warning("load_map %s: the map server answered %d", url, result)
        else:
            logger.info("load_map %s: loaded", url)

    def set_initial_pose(self, map_id: str, pose: Pose, covariance: NDArray[np.float64]) -> None:
        """Raises ValueError unless ``map_id`` is the sub-map on ``/map``."""
        self.readings.held(map_id)
        msg = PoseWithCovarianceStamped()
        msg.header.stamp, msg.header.frame_id = self._now(), self.frame
        write_initial_pose(msg, pose, covariance)
        self.readings.placed(stamp_seconds(msg.header.stamp))
        self._initial.publish(msg)

    def pose(self) -> Pose | None:
        """The pose source's latest pose, if stamped after the last initial pose."""
        if self._tf is not None:
            found = self._tf.lookup(self.frame, self.base_frame)
            if found is not None:
                self.readings.on_pose(*found)
        return self.readings.pose()

    def _on_pose(self, msg: Any) -> None:
        self.readings.on_pose(stamp_seconds(msg.header.stamp), pose_of(msg.pose.pose))

    def plan(self) -> tuple[int, Sequence[Point]]:
        return self.readings.plan()

    def _on_plan(self, msg: Any) -> None:
        self.readings.on_plan(plan_of(msg))

    def progress(self) -> str:
        return self.readings.progress()

    # --- goals -------------------------------------------------------------------------

    def send_goal(self, map_id: str, pose: Pose) -> None:
        """Raises ValueError unless ``map_id`` is the sub-map on ``/map``. The goal goes
        out once the action server is seen (within ``SERVER_WAIT`` seconds, else it
        failed); a goal sent before preempts it."""
        self.readings.held(map_id)
        goal = navigate_goal(self.frame, pose, self._now())
        with self._lock:
            self._goal += 1
            # the goal before stays the one a cancel reaches until Nav2 accepts this one:
            # it drives until then, and a cancel meanwhile must stop it too
            number, self._state, self._cancel_asked = self._goal, StackGoal.ACTIVE, False
        self.readings.on_progress("")
        threading.Thread(target=self._send, args=(number, goal), daemon=True).start()

    def _send(self, number: int, goal: Any) -> None:
        if not self._action.wait_for_server(timeout_sec=SERVER_WAIT):
            self._finish(number, StackGoal.FAILED)
            return
        sent = self._action.send_goal_async(
            goal, feedback_callback=lambda feedback: self._on_feedback(number, feedback)
        )
        sent.add_done_callback(lambda future: self._on_accepted(number, future.result()))

    def _on_accepted(self, number: int, handle: Any) -> None:
        if handle is None or not handle.accepted:
            self._finish(number, StackGoal.FAILED)
            return
        with self._lock:
            current, cancel = number == self._goal, self._cancel_asked
            if current:
                self._handle = handle
        if not current or cancel:  # preempted or cancelled while it was on its way
            handle.cancel_goal_async()
        handle.get_result_async().add_done_callback(
            lambda future: self._on_result(number, future.result())
        )

    def _on_result(self, number: int, answer: Any) -> None:
        self._finish(number, state_of_result(answer))

    def _on_feedback(self, number: int, message: Any) -> None:
        if number == self._goal:
            self.readings.on_progress(progress_of(message.feedback))

    def _finish(self, number: int, state: StackGoal) -> None:
        with self._lock:
            if number == self._goal:
                self._state = state

    def cancel(self) -> None:
        with self._lock:
            handle, self._cancel_asked = self._handle, True
        if handle is not None:
            handle.cancel_goal_async()

    def goal_state(self) -> StackGoal:
        with self._lock:
            return self._state

    def wait_for_server(self, seconds: float) -> bool:
        return bool(self._action.wait_for_server(timeout_sec=seconds))

    def _now(self) -> Any:
        return self._node.get_clock().now().to_msg()


def _tf_message() -> Any:
    from tf2_msgs.msg import TFMessage  # type: ignore[import-not-found,unused-ignore]

    return TFMessage
