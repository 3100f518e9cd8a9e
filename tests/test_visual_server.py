"""Keyframes through the real server: robots send them, the worker stores them off the
request path, admins see and clear the coverage, and relocalisation answers over REST
and rosbridge, only about the caller's own buildings. Bad input stores nothing."""

from __future__ import annotations

import base64
import io
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from channels.db import database_sync_to_async
from django.core.management import call_command

from cloudnav_core.messages import (
    CompressedImage,
    compressed_depth,
    compressed_image,
    depth_image,
)
from maps.models import Building, Keyframe
from maps.visual.worker import ingest_queue
from robots.agent.hardware import encode_jpeg
from robots.agent.sim.camera import Camera
from robots.agent.sim.world import demo_world
from tests.conftest import client_for, make_building, make_robot, make_user
from tests.support.keyframe_images import progressive_jpeg
from tests.support.keyframes import SURVEY, WAKE_UP, keyframe_body

pytestmark = pytest.mark.django_db(transaction=True)

URL = "/api/buildings/boccioni_1/maps/CorridorA/keyframes"


@pytest.fixture(autouse=True)
def keyframe_dir(tmp_path: Path, settings: Any) -> Path:
    settings.CLOUDNAV_KEYFRAME_DIR = tmp_path / "keyframes"
    return settings.CLOUDNAV_KEYFRAME_DIR


@pytest.fixture
def token(db: None) -> str:
    call_command("seed_demo", stdout=io.StringIO())
    return make_robot(name="scout", buildings=[Building.objects.get(code="boccioni_1")])[1]


@pytest.fixture
def admin(token: str) -> Any:
    """An admin of the demo building (seed_demo's own ``admin`` has a password it sets)."""
    boss = make_user("boss", "admin")
    Building.objects.get(code="boccioni_1").members.add(boss)
    return boss


@pytest.fixture(scope="module")
def camera() -> Camera:
    return Camera(demo_world(seed=0))


def send_survey(token: str, camera: Camera) -> None:
    client = client_for(token)
    for pose in SURVEY:
        assert client.post(URL, keyframe_body(camera, pose), format="json").status_code == 202
    ingest_queue().drain()


def test_a_robots_keyframes_are_stored_in_the_database_and_on_disk(
    token: str, camera: Camera, keyframe_dir: Path
) -> None:
    send_survey(token, camera)
    stored = list(Keyframe.objects.all())
    assert len(stored) >= 0.9 * len(SURVEY)  # a few views see too little to keep
    assert ingest_queue().counts.duplicates == 0
    assert all((keyframe_dir / k.path).stat().st_size == k.size for k in stored)
    assert all(k.robot == "scout" and k.points >= 20 for k in stored)
    assert {k.submap.code for k in stored} == {"CorridorA"}


def test_a_keyframe_whose_depth_is_a_raw_image_is_stored_too(token: str, camera: Camera) -> None:
    pose = (5.0, 23.2, 0.0)
    _, depth = camera.capture(pose)
    assert depth is not None
    body = {**keyframe_body(camera, pose), "depth": depth_image("camera", depth, 1.0)}
    assert client_for(token).post(URL, body, format="json").status_code == 202
    ingest_queue().drain()
    assert Keyframe.objects.count() == 1


def test_a_near_duplicate_keyframe_is_dropped(token: str, camera: Camera) -> None:
    client = client_for(token)
    for pose in [(5.0, 23.2, 0.0), (5.05, 23.2, 0.03), (5.0, 23.2, 0.5)]:
        assert client.post(URL, keyframe_body(camera, pose), format="json").status_code == 202
    ingest_queue().drain()
    assert Keyframe.objects.count() == 2


def test_admins_see_the_coverage_and_clear_it(
    token: str, camera: Camera, admin: Any, keyframe_dir: Path
) -> None:
    client_for(token).post(URL, keyframe_body(camera, (5.0, 23.2, 0.0)), format="json")
    ingest_queue().drain()
    listed = client_for(admin).get(URL)
    assert listed.status_code == 200, listed.content
    coverage = listed.json()["keyframes"]
    assert [(round(k["x"], 2), round(k["y"], 2)) for k in coverage] == [(5.0, 23.2)]
    assert client_for(token).delete(URL).status_code == 403
    assert client_for(admin).delete(URL).json() == {"removed": 1}
    assert Keyframe.objects.count() == 0
    assert not list(keyframe_dir.rglob("*.npz"))


def test_a_robot_wakes_up_and_is_placed_over_rest(token: str, camera: Camera) -> None:
    send_survey(token, camera)
    image = compressed_image(
        "camera", encode_jpeg(Camera(demo_world(seed=0), seed=9).render(WAKE_UP)), 2.0
    )
    answer = client_for(token).post("/api/relocalise", {"images": [image]}, format="json").json()
    assert answer["localised"], answer
    assert answer["map_id"] == "boccioni_1/CorridorA"
    assert math.hypot(answer["pose"]["x"] - WAKE_UP[0], answer["pose"]["y"] - WAKE_UP[1]) < 0.15
    assert abs(answer["pose"]["yaw"] - WAKE_UP[2]) < math.radians(3)
    assert len(answer["covariance"]) == 9
    assert answer["inliers"] >= 40
    assert answer["keyframes"]
    assert answer["reason"] == ""


def test_images_of_another_building_are_not_localised(token: str, camera: Camera) -> None:
    send_survey(token, camera)
    elsewhere = Camera(demo_world(seed=0, building_code="elsewhere_9")).render(WAKE_UP)
    body = {"images": [compressed_image("camera", encode_jpeg(elsewhere), 2.0)]}
    answer = client_for(token).post("/api/relocalise", body, format="json").json()
    assert answer["localised"] is False
    assert answer["reason"]
    assert answer["map_id"] == ""


def test_a_robot_may_not_ask_about_another_building(token: str, camera: Camera) -> None:
    other = make_building(code="other_1")
    _, stranger = make_robot(name="stranger", buildings=[other])
    body = {"images": [keyframe_body(camera, WAKE_UP)["image"]], "building": "boccioni_1"}
    assert client_for(stranger).post("/api/relocalise", body, format="json").status_code == 403
    assert (
        client_for(stranger).post(URL, keyframe_body(camera, WAKE_UP), format="json").status_code
        == 403
    )
    assert client_for(None).post("/api/relocalise", body, format="json").status_code in (401, 403)


def test_a_person_with_no_building_is_refused(token: str, camera: Camera) -> None:
    """Issue 23 point 13: they got answers (a search of no keyframes)."""
    body = {"images": [keyframe_body(camera, WAKE_UP)["image"]]}
    for person in (make_user("outsider"), make_user("lonely", "operator")):
        answer = client_for(person).post("/api/relocalise", body, format="json")
        assert answer.status_code == 403, answer.content
        assert "no building" in answer.json()["detail"]
        named = client_for(person).post(
            "/api/relocalise", {**body, "building": "boccioni_1"}, format="json"
        )
        assert named.status_code == 403, named.content


def test_a_viewer_may_not_relocalise_but_an_operator_may(surveyed: str, camera: Camera) -> None:
    """Relocalisation places a robot: its robots and those who may drive it ask; a viewer
    has no robot to place, and each question costs the server tens of milliseconds."""
    building = Building.objects.get(code="boccioni_1")
    viewer, operator = make_user("vera", "viewer"), make_user("otto", "operator")
    building.members.add(viewer, operator)
    image = compressed_image(
        "camera", encode_jpeg(Camera(demo_world(seed=0), seed=9).render(WAKE_UP)), 2.0
    )
    refused = client_for(viewer).post("/api/relocalise", {"images": [image]}, format="json")
    assert refused.status_code == 403, refused.content
    answer = client_for(operator).post("/api/relocalise", {"images": [image]}, format="json")
    assert answer.status_code == 200, answer.content
    assert answer.json()["map_id"] == "boccioni_1/CorridorA"


def jpeg_of(pixels: np.ndarray) -> CompressedImage:
    return compressed_image("camera", encode_jpeg(pixels), 1.0)


@pytest.mark.parametrize(
    ("change", "complaint"),
    [
        (
            lambda b: {**b, "image": {**b["image"], "data": base64.b64encode(b"hello").decode()}},
            "not an image",
        ),
        (
            lambda b: {
                **b,
                "image": {
                    **b["image"],
                    "data": b["image"]["data"][: len(b["image"]["data"]) // 2 // 4 * 4],
                },
            },
            "truncated",
        ),
        (lambda b: {**b, "image": jpeg_of(np.zeros((1200, 1600), np.uint8))}, "pixels"),
        (
            lambda b: {**b, "depth": depth_image("camera", np.ones((240, 320), np.float32), 1.0)},
            "does not match",
        ),
        (
            lambda b: {
                **b,
                "depth": compressed_depth("camera", np.ones((240, 320), np.float32), 1.0),
            },
            "does not match",
        ),
        (
            lambda b: {**b, "depth": {**b["depth"], "data": b["depth"]["data"][:4000]}},
            "compressedDepth",
        ),
        (lambda b: {**b, "pose": {"x": 500.0, "y": 3.0, "yaw": 0.0}}, "not on the free floor"),
        (lambda b: {**b, "pose": {"x": "NaN", "y": 3.0, "yaw": 0.0}}, "finite"),
        (lambda b: {k: v for k, v in b.items() if k != "depth"}, "depth"),
        # Issue 23 point 16: these were answered 500.
        (lambda b: {**b, "depth": {**raw_depth(), "height": -480, "width": -640}}, "depth"),
        (lambda b: {**b, "pose": {"x": 1e308, "y": 3.0, "yaw": 0.0}}, "within"),
        (lambda b: {**b, "mount": {"forward": 1e308, "height": 0.25}}, "mount"),
        (lambda b: {**b, "camera_info": {"K": [525, 0, 1e308, 0, 525, 239.5, 0, 0, 1]}}, "K"),
        # Issue 23 point 13: decoding it took 14 s of CPU.
        (lambda b: {**b, "image": many_scans()}, "scans"),
    ],
)
def test_bad_keyframes_get_a_clear_error_and_store_nothing(
    token: str, camera: Camera, change: Any, complaint: str, keyframe_dir: Path
) -> None:
    body = change(keyframe_body(camera, (5.0, 23.2, 0.0)))
    response = client_for(token).post(URL, body, format="json")
    ingest_queue().drain()
    assert response.status_code == 400, response.content
    assert complaint in response.json()["detail"]
    assert Keyframe.objects.count() == 0
    assert not keyframe_dir.exists() or not list(keyframe_dir.rglob("*.npz"))


def raw_depth() -> dict[str, Any]:
    return dict(depth_image("camera", np.ones((480, 640), np.float32), 1.0))


def many_scans() -> CompressedImage:
    return compressed_image("camera", progressive_jpeg(50_000), 1.0)


@pytest.mark.parametrize(
    ("change", "field"),
    [
        (lambda b: {**b, "depth": {**raw_depth(), "height": -480, "width": -640}}, "depth"),
        (lambda b: {**b, "pose": {"x": 1e308, "y": 3.0, "yaw": 0.0}}, "pose"),
        (lambda b: {**b, "image": many_scans()}, "image"),
    ],
)
def test_a_bad_keyframe_is_answered_with_the_field_at_fault(
    token: str, camera: Camera, change: Any, field: str
) -> None:
    body = change(keyframe_body(camera, (5.0, 23.2, 0.0)))
    answer = client_for(token).post(URL, body, format="json")
    assert answer.status_code == 400, answer.content
    assert list(answer.json()) == ["detail", field]
    assert answer.json()["detail"] == f"{field}: {answer.json()[field][0]}"


def test_a_bad_relocalisation_request_is_refused(token: str, camera: Camera) -> None:
    client = client_for(token)
    good = keyframe_body(camera, WAKE_UP)
    for body, complaint in [
        ({"images": []}, "images"),
        ({"images": [{"data": "!!"}]}, "base64"),
        (
            {
                "images": [good["image"]],
                "depth": depth_image("camera", np.ones((10, 10), np.float32), 1),
            },
            "does not match",
        ),
        ({"images": [good["image"], many_scans()]}, "images[1]: a JPEG of 50000 scans"),
        ({"images": [good["image"]], "mount": {"forward": 1e308, "height": 0.25}}, "mount"),
        (
            {"images": [good["image"]], "camera_info": {"K": [1e-300, 0, 320, 0, 1, 240, 0, 0, 1]}},
            "camera_info",
        ),
    ]:
        response = client.post("/api/relocalise", body, format="json")
        assert response.status_code == 400, body
        assert complaint in response.json()["detail"]


@pytest.fixture
def surveyed(token: str, camera: Camera) -> str:
    """The robot's token, once its survey of Corridor A is stored."""
    send_survey(token, camera)
    return token


async def test_relocalise_is_a_rosbridge_service(rosbridge: Any, surveyed: str) -> None:
    token = surveyed
    image = compressed_image(
        "camera", encode_jpeg(Camera(demo_world(seed=0), seed=9).render(WAKE_UP)), 2.0
    )
    robot = await rosbridge(token=token)
    await robot.send(
        op="call_service",
        id="where",
        service="cloudnav/relocalise",
        args={"images": [image], "building": "boccioni_1"},
    )
    answer = await robot.receive(60)
    assert answer["result"] is True, answer
    assert answer["values"]["localised"] is True
    assert answer["values"]["map_id"] == "boccioni_1/CorridorA"
    await robot.send(
        op="call_service", id="bad", service="cloudnav/relocalise", args={"images": "nope"}
    )
    refused = await robot.receive(60)
    assert refused["result"] is False
    await robot.send(
        op="call_service",
        id="other",
        service="cloudnav/relocalise",
        args={"images": [image], "building": "other_1"},
    )
    assert (await robot.receive(60))["result"] is False


async def test_a_viewer_may_not_relocalise_over_rosbridge(rosbridge: Any, surveyed: str) -> None:
    viewer = await database_sync_to_async(make_user)("vera", "viewer")
    building = await Building.objects.aget(code="boccioni_1")
    await database_sync_to_async(building.members.add)(viewer)
    image = compressed_image(
        "camera", encode_jpeg(Camera(demo_world(seed=0), seed=9).render(WAKE_UP)), 2.0
    )
    socket = await rosbridge(user=viewer)
    await socket.send(
        op="call_service", id="where", service="/cloudnav/relocalise", args={"images": [image]}
    )
    refused = await socket.receive(60)
    assert refused["result"] is False, refused
    assert "no building" in refused["values"]
