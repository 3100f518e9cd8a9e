"""The agent's side of the visual map: keyframes spaced out and well formed, answers read
into a pose estimate, failures never raised."""

from __future__ import annotations

import json
import math
from typing import Any

import httpx
import numpy as np
from numpy.typing import NDArray

from cloudnav_core.camera import CameraModel
from cloudnav_core.messages import depth_of
from cloudnav_core.params import RobotConfig
from cloudnav_core.se2 import Pose
from robots.agent.robot import PoseTracker, Robot
from robots.agent.sim.hardware import SimHardware
from robots.agent.sim.world import demo_world
from robots.agent.supervisor.bundle_cache import BundleCache
from robots.agent.supervisor.maps_supervisor import MapsSupervisor
from robots.agent.supervisor.submaps import SubMap
from robots.agent.visual import LOST_SPREAD, VisualMap

IMAGE = np.zeros((480, 640), np.uint8)
DEPTH = np.full((480, 640), 2.0, np.float32)


def visual_map(handler: object) -> tuple[VisualMap, list[httpx.Request]]:
    seen: list[httpx.Request] = []

    def record(request: httpx.Request) -> httpx.Response:
        seen.append(request)
        return handler(request)  # type: ignore[operator]

    http = httpx.AsyncClient(base_url="http://cloud", transport=httpx.MockTransport(record))
    return VisualMap(http, CameraModel()), seen


async def test_keyframes_go_out_every_30_cm_or_15_degrees_with_image_depth_and_pose() -> None:
    visual, seen = visual_map(lambda _request: httpx.Response(202, json={"queued": True}))
    assert visual.keyframe_due("b/A", (1.0, 2.0, 0.0))
    await visual.send_keyframe("b/A", (1.0, 2.0, 0.0), IMAGE, DEPTH)
    assert not visual.keyframe_due("b/A", (1.2, 2.0, 0.1))
    assert visual.keyframe_due("b/A", (1.31, 2.0, 0.0))
    assert visual.keyframe_due("b/A", (1.0, 2.0, math.radians(16)))
    assert visual.keyframe_due("b/B", (1.0, 2.0, 0.0))  # another sub-map starts afresh
    (request,) = seen
    assert request.url.path == "/api/buildings/b/maps/A/keyframes"
    body = json.loads(request.content)
    assert body["pose"] == {"x": 1.0, "y": 2.0, "yaw": 0.0}
    assert body["image"]["format"] == "jpeg"
    assert body["depth"]["format"] == "16UC1; compressedDepth png"
    depth = depth_of(body["depth"], 640 * 480)
    assert depth is not None
    assert np.array_equal(depth, DEPTH)
    assert len(request.content) < 20_000  # the raw 16UC1 image alone is 614 kB of base64
    assert body["camera_info"]["K"][0] == 525.0
    assert visual.sent == 1


async def test_a_refused_keyframe_is_counted_and_not_raised() -> None:
    visual, _ = visual_map(lambda _request: httpx.Response(503, json={"detail": "full"}))
    await visual.send_keyframe("b/A", (1.0, 2.0, 0.0), IMAGE, DEPTH)
    assert (visual.sent, visual.refused, visual.busy) == (0, 1, False)


async def test_a_localised_answer_becomes_a_pose_estimate() -> None:
    answer = {
        "localised": True, "map_id": "b/A", "pose": {"x": 3.0, "y": 4.0, "yaw": 0.5},
        "covariance": [0.01, 0, 0, 0, 0.01, 0, 0, 0, 0.001], "inliers": 120,
        "keyframes": [1, 2], "image": 0, "reason": "",
    }  # fmt: skip
    visual, seen = visual_map(lambda _request: httpx.Response(200, json=answer))
    placement = await visual.ask(IMAGE, 5.0, "b")
    assert placement is not None
    assert placement.map_id == "b/A"
    assert (placement.estimate.x, placement.estimate.y, placement.estimate.yaw) == (3.0, 4.0, 0.5)
    assert placement.estimate.covariance[2, 2] == 0.001
    assert json.loads(seen[0].content)["building"] == "b"
    assert not visual.may_ask(6.0)  # at most every two seconds
    assert visual.may_ask(7.0)


async def test_not_localised_or_unreachable_gives_no_placement() -> None:
    visual, _ = visual_map(
        lambda _request: httpx.Response(200, json={"localised": False, "reason": "no"})
    )
    assert await visual.ask(IMAGE, 0.0) is None

    def unreachable(request: httpx.Request) -> httpx.Response:
        raise httpx.ConnectError("down")

    visual, _ = visual_map(unreachable)
    assert await visual.ask(IMAGE, 0.0) is None
    assert not visual.busy


# --- the lost path: a filter whose spread grows past the bound asks the cloud ---------


class _Filter:
    """A particle filter's interface, its spread (``visual.spread`` of its covariance)
    set by the test."""

    def __init__(self) -> None:
        self.spread = 0.05
        self.resets: list[Pose] = []

    def reset(self, pose: Pose, covariance: NDArray[np.float64]) -> None:
        self.resets.append(pose)
        self.spread = math.sqrt(float(covariance[0, 0] + covariance[1, 1]))

    def predict(self, odom_delta: Pose) -> None: ...
    def update(self, scan: Any) -> bool:  # noqa: ARG002 (the interface's)
        return True

    def pose(self) -> Pose:
        return self.resets[-1] if self.resets else (0.0, 0.0, 0.0)

    def covariance(self) -> NDArray[np.float64]:
        return np.diag([self.spread**2 / 2, self.spread**2 / 2, 0.01])  # spread() reads it back

    def set_map(self, grid: Any, resolution: float, origin: Pose) -> None: ...


class _Silent:
    async def publish(self, _topic: str, _msg: dict[str, Any]) -> bool:
        return True


class _Recorder:
    def __init__(self) -> None:
        self.sent: list[tuple[str, dict[str, Any]]] = []

    async def publish(self, topic: str, msg: dict[str, Any]) -> bool:
        self.sent.append((topic, msg))
        return True


async def depth_topics(config: RobotConfig) -> dict[str, dict[str, Any]]:
    """The depth and camera topics a robot publishing ``config`` sent in one second."""
    hardware = SimHardware(demo_world(), (3.0, 4.0, 0.0), seed=1)
    tracker = PoseTracker(lambda _submap: _Filter())
    supervisor = MapsSupervisor(_Maps(httpx.AsyncClient(base_url="http://cloud")), tracker)
    recorder = _Recorder()
    robot = Robot(hardware, supervisor, tracker, recorder, config, 0.0)
    for _ in range(10):
        await robot.tick()
    return {topic: msg for topic, msg in recorder.sent if topic.startswith("camera/")}


async def test_depth_goes_out_as_compressed_depth_and_raw_only_on_request() -> None:
    sent = await depth_topics(RobotConfig(camera_rate=0, depth_rate=1.0))
    assert set(sent) == {"camera/depth/image/compressedDepth", "camera/camera_info"}
    message = sent["camera/depth/image/compressedDepth"]
    assert message["format"] == "16UC1; compressedDepth png"
    assert message["header"]["frame_id"] == sent["camera/camera_info"]["header"]["frame_id"]
    depth = depth_of(message, 640 * 480)
    assert depth is not None
    assert depth.shape == (480, 640)
    assert len(message["data"]) < 20_000  # the raw 16UC1 image is 819 kB of base64
    raw = await depth_topics(RobotConfig(camera_rate=0, depth_rate=1.0, raw_depth=True))
    assert raw["camera/depth/image"]["encoding"] == "16UC1"
    same = depth_of(raw["camera/depth/image/compressedDepth"], 640 * 480)
    unpacked = depth_of(raw["camera/depth/image"], 640 * 480)
    assert same is not None
    assert unpacked is not None
    assert np.array_equal(unpacked, same, equal_nan=True)


class _Maps(BundleCache):
    """Bundles made on the spot: an empty room, for any Map ID."""

    async def load(self, map_id: str) -> SubMap:
        building, _, code = map_id.partition("/")
        grid = np.zeros((100, 100), np.int8)
        return SubMap(building, code, "1", '"1"', grid, 0.1, (0.0, 0.0, 0.0), {}, (code,), ())


async def lost_robot(handler: object) -> tuple[Robot, _Filter, list[httpx.Request]]:
    """A robot localised in b/A with a particle filter, its cloud answering ``handler``."""
    visual, seen = visual_map(handler)
    hardware = SimHardware(demo_world(), (3.0, 4.0, 0.0), seed=1)
    made = _Filter()
    tracker = PoseTracker(lambda _submap: made)
    maps = _Maps(visual.http)
    supervisor = MapsSupervisor(maps, tracker)
    robot = Robot(hardware, supervisor, tracker, _Silent(), RobotConfig(camera_rate=0), 0.0, visual)
    supervisor.make_current(await maps.load("b/A"))
    tracker.reset((3.0, 4.0, 0.0), np.diag([0.01, 0.01, 0.001]), tracker.odom)
    return robot, made, seen


async def test_a_filter_spread_past_the_bound_asks_the_cloud_and_takes_its_answer() -> None:
    answer = {
        "localised": True, "map_id": "b/B", "pose": {"x": 5.0, "y": 6.0, "yaw": 1.0},
        "covariance": [0.004, 0, 0, 0, 0.004, 0, 0, 0, 0.001], "inliers": 90,
        "keyframes": [7], "image": 0, "reason": "",
    }  # fmt: skip
    robot, made, seen = await lost_robot(lambda _request: httpx.Response(200, json=answer))
    robot.seconds = 10.0
    made.spread = LOST_SPREAD * 0.9  # uncertain, not lost: keyframes stop, no question
    robot._use_visual_map(IMAGE, None)
    await robot.settle()
    assert seen == []
    made.spread = LOST_SPREAD * 1.1  # lost: it asks, naming the building it was in
    robot._use_visual_map(IMAGE, None)
    await robot.settle()
    assert [r.url.path for r in seen] == ["/api/relocalise"]
    assert json.loads(seen[0].content)["building"] == "b"
    assert robot.supervisor.current is not None
    assert robot.supervisor.current.map_id == "b/B"
    assert robot.supervisor.placed_by == "visual relocalisation"
    assert made.resets[-1] == (5.0, 6.0, 1.0)
    assert robot.tracker.spread() < LOST_SPREAD  # placed: no more questions
    robot.seconds = 20.0
    robot._use_visual_map(IMAGE, None)
    await robot.settle()
    assert len(seen) == 1


async def test_a_lost_robot_asks_at_most_every_two_seconds_and_keeps_its_map_on_no() -> None:
    no = {"localised": False, "reason": "the pose is too uncertain (0.40 m)"}
    robot, made, seen = await lost_robot(lambda _request: httpx.Response(200, json=no))
    made.spread = LOST_SPREAD * 2
    for seconds in (10.0, 10.5, 11.9, 12.0):
        robot.seconds = seconds
        robot._use_visual_map(IMAGE, None)
        await robot.settle()
    assert len(seen) == 2  # at 10.0 and 12.0
    assert robot.supervisor.current is not None
    assert robot.supervisor.current.map_id == "b/A"  # "not localised" changes nothing
    assert len(made.resets) == 1
