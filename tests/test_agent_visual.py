"""The agent's side of the visual map: keyframes spaced out and well formed, answers read
into a pose estimate, failures never raised."""

from __future__ import annotations

import json
import math

import httpx
import numpy as np

from robots.agent.perception import CameraModel
from robots.agent.visual import VisualMap

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
    assert body["depth"]["encoding"] == "16UC1"
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
